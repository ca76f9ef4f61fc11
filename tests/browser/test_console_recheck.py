"""The tool page's Re-check (issue 41) in a real Chromium: shown when the robot has a
controller and a reference point; it asks for the point and a reason, and says the answer's
summary and the correction (version, delta, deployment in words).

A live server (SQLite, one worker) and a KUKAVARPROXY simulator in this process; the robot is
placed as tests/api/test_recheck_controllers.py places it: the flange such that flange @ the
true TCP is the reference point."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import httpx
import numpy as np
import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.api.controller_rigs import Rig, rig
from tests.api.test_capture_controllers import KukaCell
from tests.api.test_deployments import WRITE_REQUEST
from tests.api.test_recheck_controllers import (
    ACTIVE_POSITION,
    ACTIVE_Q,
    CRASHED,
    MOVED,
    REFERENCE,
    STANDING,
)
from tests.browser.conftest import confirm, sign_in_to
from tests.controllers.simbase import go_silent

pytestmark = [pytest.mark.live, pytest.mark.browser]


@dataclass
class Cell:
    server: LiveServer
    rig: Rig
    tool_id: str
    #: a tool on a robot with a controller and no reference point; one on a robot with a
    #: reference point and no controller
    no_point_tool_id: str
    no_controller_tool_id: str


def _robot_with_tool(http: httpx.Client, name: str, controller: dict[str, object] | None) -> str:
    robot = http.post("/v1/robots", json={"name": name, "cell": "weld-1"}).json()
    if controller is not None:
        http.put(f"/v1/robots/{robot['id']}/controller", json=controller).raise_for_status()
    tool = http.post(
        f"/v1/robots/{robot['id']}/tools",
        json={"name": "torch", "slot": 3, "tolerance": {"check_mm": 0.5, "max_correction_mm": 2}},
    ).json()
    body = {"method": "manual", "tcp": {"position_mm": ACTIVE_POSITION, "quaternion": ACTIVE_Q}}
    http.post(f"/v1/tools/{tool['id']}/calibrations", json=body).raise_for_status()
    return str(tool["id"])


def _point(http: httpx.Client, tool_id: str) -> None:
    robot_id = http.get(f"/v1/tools/{tool_id}").json()["robot_id"]
    http.post(
        f"/v1/robots/{robot_id}/reference-points",
        json={"name": "pin", "position_mm": [float(v) for v in REFERENCE]},
    ).raise_for_status()


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("console-recheck")
    with (
        rig("kuka_kvp") as r,
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
        server.client() as http,
    ):
        tool_id = _robot_with_tool(http, "kr16-weld", r.controller_body())
        _point(http, tool_id)
        http.post(f"/v1/tools/{tool_id}/deployments", json={}).raise_for_status()
        no_point = _robot_with_tool(http, "kr16-spare", r.controller_body())
        no_controller = _robot_with_tool(http, "kr16-bench", None)
        _point(http, no_controller)
        yield Cell(server, r, tool_id, no_point, no_controller)


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return cell.server


def _stand(cell: Cell, moved: np.ndarray) -> None:
    """The flange placed so that flange @ (active TCP + moved) is the reference point."""
    KukaCell(cell.rig).place(STANDING, REFERENCE - STANDING @ (np.asarray(ACTIVE_POSITION) + moved))


def _recheck(page: Page, reason: str) -> None:
    page.select_option(
        "#recheck-point", label=f"pin ({', '.join(f'{v:.3f}' for v in REFERENCE)} mm)"
    )
    page.click("#recheck-button")
    dialog = page.locator("dialog#confirm")
    expect(dialog).to_contain_text("Re-check torch at pin?")
    expect(dialog).to_contain_text("at most 2.000 mm")
    confirm(page, reason)


def test_recheck_refuses_5_mm_then_corrects_deploys_and_says_so(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.tool_id}")
    expect(page.locator("#recheck-button")).to_be_visible()
    held = cell.rig.native()

    _stand(cell, CRASHED)
    _recheck(page, "torch hit the clamp")
    answer = page.locator("#recheck-outcome .recheck-answer")
    expect(answer).to_have_attribute("data-verdict", "recalibrate")
    expect(answer).to_contain_text("Recalibrate: nothing changed")
    expect(answer).to_contain_text("nothing was changed: recalibrate")
    expect(page.locator("#recheck-version")).to_have_count(0)
    expect(page.locator("#versions tbody tr")).to_have_count(1)
    assert cell.rig.native() == held

    _stand(cell, MOVED)
    _recheck(page, "wire stuck, torch bent")
    expect(answer).to_have_attribute("data-verdict", "corrected")
    expect(answer).to_contain_text("corrected: version 2")
    expect(page.locator("#recheck-version")).to_have_text("v2 (was v1), active")
    expect(page.locator("#recheck-delta")).to_contain_text("(0.943 mm, flange frame)")
    delta = page.locator("#recheck-delta").inner_text().split(" mm")[0].split(", ")
    np.testing.assert_allclose([float(v) for v in delta], MOVED, atol=0.02)
    deployment = page.locator("#recheck-deployment")
    expect(deployment).to_contain_text("verified")
    expect(deployment).to_contain_text("the controller holds v2")
    # the page is drawn again with the new version active and its activation's kind and reason
    expect(page.locator("#versions tbody tr")).to_have_count(2)
    expect(page.locator("#versions tr.active")).to_have_attribute("data-version", "2")
    expect(page.locator("#activations tbody tr").first).to_contain_text("check_correction")
    expect(page.locator("#activations tbody tr").first).to_contain_text("wire stuck, torch bent")
    with cell.server.client() as http:
        active = http.get(f"/v1/tools/{cell.tool_id}/tcp").json()["tcp"]
    truth = np.asarray(ACTIVE_POSITION) + MOVED
    assert np.linalg.norm(np.asarray(active["position_mm"]) - truth) < 0.02
    cell.rig.assert_holds(active["position_mm"], active["quaternion"])


def test_no_recheck_without_a_reference_point_or_a_controller(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.no_point_tool_id}")
    expect(page.locator("#deploy-button")).to_be_visible()
    expect(page.locator("#recheck")).to_have_count(0)
    page.goto(f"{cell.server.url}/ui/tools/{cell.no_controller_tool_id}")
    expect(page.locator("main")).to_have_attribute("aria-busy", "false")
    expect(page.locator("#controller-none")).to_be_visible()
    expect(page.locator("#recheck")).to_have_count(0)


def test_a_deployment_that_fails_is_said_and_the_correction_stays_active(
    page: Page, cell: Cell
) -> None:
    """The write is sent and never answered: the new version is active in tcpcal, the page
    says the deployment's status in words and that the controller may hold either."""
    with cell.server.client() as http:
        served = http.get(f"/v1/tools/{cell.tool_id}/tcp").json()
    before = int(served["version"])
    truth = np.asarray(served["tcp"]["position_mm"]) + MOVED
    # the active version is oriented as version 1 (a correction keeps the orientation)
    KukaCell(cell.rig).place(STANDING, REFERENCE - STANDING @ truth)
    cell.rig.sim.fault = go_silent("before", WRITE_REQUEST["kuka_kvp"])
    sign_in_to(page, cell.server, f"/ui/tools/{cell.tool_id}")
    _recheck(page, "clamp again")
    answer = page.locator("#recheck-outcome .recheck-answer")
    expect(answer).to_have_attribute("data-verdict", "deployment_failed")
    expect(answer).to_contain_text("Corrected, deployment failed")
    expect(answer).to_contain_text("the controller is flagged")
    expect(page.locator("#recheck-version")).to_have_text(f"v{before + 1} (was v{before}), active")
    deployment = page.locator("#recheck-deployment")
    expect(deployment).to_contain_text("written, not confirmed")
    expect(deployment).to_contain_text(f"may hold v{before + 1} or v{before}")
    expect(page.locator("#versions tr.active")).to_have_attribute("data-version", str(before + 1))
    cell.rig.sim.stalled = False  # the controller answers again, for the next test


def test_measure_only_changes_nothing_and_a_read_key_sees_no_recheck(
    page: Page, cell: Cell
) -> None:
    """With "correct" unticked the re-check only measures: out of tolerance, not corrected,
    no version and no controller value changed. A read key gets no Re-check."""
    with cell.server.client() as http:
        served = http.get(f"/v1/tools/{cell.tool_id}/tcp").json()
        read_key = http.post("/v1/keys", json={"name": "viewer", "scope": "read"}).json()["key"]
    versions = int(served["version"])
    truth = np.asarray(served["tcp"]["position_mm"]) + MOVED
    KukaCell(cell.rig).place(STANDING, REFERENCE - STANDING @ truth)
    held = cell.rig.native()
    sign_in_to(page, cell.server, f"/ui/tools/{cell.tool_id}")
    page.uncheck("#recheck-correct")
    page.click("#recheck-button")
    expect(page.locator("dialog#confirm")).to_contain_text("Only measured: nothing changes")
    confirm(page, "after the clamp was moved")
    answer = page.locator("#recheck-outcome .recheck-answer")
    expect(answer).to_have_attribute("data-verdict", "out_of_tolerance")
    expect(answer).to_contain_text("Out of tolerance, not corrected")
    expect(page.locator("#recheck-version")).to_have_count(0)
    expect(page.locator("#versions tr.active")).to_have_attribute("data-version", str(versions))
    assert cell.rig.native() == held

    page.evaluate("sessionStorage.clear()")
    sign_in_to(page, cell.server, f"/ui/tools/{cell.tool_id}", key=read_key)
    expect(page.locator("#controller-state")).to_be_visible()
    expect(page.locator("#recheck")).to_have_count(0)
