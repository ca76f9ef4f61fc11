"""The frame page's controller section (issue 48) in a real Chromium against a live server and
a KUKAVARPROXY simulator: the frame's controller state, the Deploy button asking the tools'
confirmation (the version, the frame, the controller's place), then "verified", the
deployment in the history and the state in sync."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.api.controller_rigs import Rig, rig
from tests.browser.conftest import sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]

POSITION = [1200.0, -350.0, 420.0]


@dataclass
class Cell:
    server: LiveServer
    rig: Rig
    robot_id: str
    frame_id: str


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("console-frame-controller")
    with (
        rig("kuka_kvp") as r,
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
        server.client() as http,
    ):
        robot = http.post("/v1/robots", json={"name": "kr16-weld", "vendor": "KUKA"}).json()
        http.put(
            f"/v1/robots/{robot['id']}/controller", json=r.controller_body()
        ).raise_for_status()
        frame = http.post(
            f"/v1/robots/{robot['id']}/frames", json={"name": "table", "kind": "base", "slot": 3}
        ).json()
        manual = {"method": "manual", "frame": {"position_mm": POSITION}}
        http.post(f"/v1/frames/{frame['id']}/calibrations", json=manual).raise_for_status()
        yield Cell(server, r, robot["id"], frame["id"])


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return cell.server


def test_a_frame_is_deployed_after_the_confirmation_and_reads_in_sync(
    page: Page, cell: Cell
) -> None:
    expect.set_options(timeout=20_000)
    sign_in_to(page, cell.server, f"/ui/frames/{cell.frame_id}/calibrate")
    state = page.locator("#controller-state")
    expect(state).to_contain_text("kuka_kvp at 127.0.0.1")
    expect(state).to_contain_text("not compared yet")
    expect(page.locator("#no-deployments")).to_be_visible()
    page.click("#deploy-button")
    confirm = page.locator("#deploy-confirm")
    expect(confirm).to_be_visible()
    expect(confirm).to_contain_text(
        f"Write version 1 of table into the controller at 127.0.0.1:{cell.rig.sim.port} (kuka_kvp)"
        " and read it back? The robot moves in this frame from then on."
    )
    page.click("#deploy-no")  # cancelled: nothing written
    expect(confirm).to_be_hidden()
    assert cell.rig.sim.base_data(3)[:3] == (0.0, 0.0, 0.0)
    page.click("#deploy-button")
    page.click("#deploy-yes")
    expect(page.locator("#deploy-outcome")).to_contain_text(
        "Verified: BASE_DATA[3] holds version 1"
    )
    rows = page.locator("#deployments tbody tr")
    expect(rows).to_have_count(1)
    expect(rows.first).to_have_attribute("data-status", "verified")
    expect(rows.first).to_contain_text("the controller holds v1")
    assert cell.rig.sim.base_data(3)[:3] == pytest.approx(tuple(POSITION), abs=1e-3)
    expect(state.locator(".badge")).to_have_text("in sync")
    expect(state).to_contain_text("against v1")
    expect.set_options(timeout=5_000)


def test_a_ur_frame_says_why_it_is_not_written_and_which_file_to_load(
    page: Page, cell: Cell
) -> None:
    expect.set_options(timeout=20_000)
    with rig("ur_rtde") as r, cell.server.client() as http:
        robot = http.post("/v1/robots", json={"name": "ur10-glue", "vendor": "UR"}).json()
        http.put(
            f"/v1/robots/{robot['id']}/controller", json=r.controller_body()
        ).raise_for_status()
        frame = http.post(
            f"/v1/robots/{robot['id']}/frames", json={"name": "fixture", "kind": "base"}
        ).json()
        manual = {"method": "manual", "frame": {"position_mm": POSITION}}
        http.post(f"/v1/frames/{frame['id']}/calibrations", json=manual).raise_for_status()
        sign_in_to(page, cell.server, f"/ui/frames/{frame['id']}/calibrate")
        page.click("#deploy-button")
        expect(page.locator("#deploy-confirm")).to_contain_text("Write version 1 of fixture")
        page.click("#deploy-yes")
        refused = page.locator("#deploy-outcome [role=alert]")
        expect(refused).to_contain_text("Not written: tcpcal cannot write this frame")
        expect(refused.locator(".reason")).to_contain_text("Why: ")
        expect(refused.locator(".file")).to_contain_text("on the controller by hand instead")
        expect(refused.locator(".file")).not_to_contain_text("undefined")
    expect.set_options(timeout=5_000)
