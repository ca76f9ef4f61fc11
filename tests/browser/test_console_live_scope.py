"""A robot with one live TCP (contract v1.3 scope "live": UR, Techman) on the console, in a
real Chromium: where its controller is reached (each service's port), what "live" means
said in words before and after a deployment (the next program start sets its own TCP), the
deployment's scope in the deployments table, and the robot's other tool `not_live` in words
on the fleet and on its own page.

A live server (SQLite, one worker) and the UR simulator in this process, on ports of its
own (the controller's `ports`)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.api.controller_rigs import Rig, rig
from tests.browser.conftest import sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]

GLUE = {"position_mm": [1.5, -2.0, 182.25], "quaternion": [1.0, 0.0, 0.0, 0.0]}
GRIPPER = {"position_mm": [0.0, 0.0, 120.0], "quaternion": [1.0, 0.0, 0.0, 0.0]}
#: What the console says a live deployment means (the contract's words: the next program
#: start sets its own TCP).
NEXT_START = "the next program start sets its own TCP"


@dataclass
class Cell:
    server: LiveServer
    rig: Rig
    robot_id: str
    glue_id: str
    gripper_id: str


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("console-live-scope")
    with (
        rig("ur_rtde") as r,
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
        server.client() as http,
    ):
        robot = http.post("/v1/robots", json={"name": "ur10e-glue", "cell": "glue-1"}).json()
        put = http.put(f"/v1/robots/{robot['id']}/controller", json=r.controller_body())
        put.raise_for_status()
        ids = []
        for name, tcp in (("glue-gun", GLUE), ("gripper", GRIPPER)):
            tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": name}).json()
            body = {"method": "manual", "tcp": tcp}
            http.post(f"/v1/tools/{tool['id']}/calibrations", json=body).raise_for_status()
            ids.append(tool["id"])
        yield Cell(server, r, robot["id"], *ids)


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return cell.server


def _open(page: Page, cell: Cell, path: str) -> None:
    """Another page of the console, signed in already (the key is kept for the session)."""
    page.goto(cell.server.url + path)
    expect(page.locator("main")).to_have_attribute("aria-busy", "false")


def test_a_live_deployment_says_what_live_means_and_the_other_tool_is_not_live(
    page: Page, cell: Cell
) -> None:
    ports = f"rtde {cell.rig.sim.rtde_port}, secondary {cell.rig.sim.secondary_port}"
    sign_in_to(page, cell.server, f"/ui/tools/{cell.glue_id}")
    # where the controller is reached: each service's port, as the API answers them
    expect(page.locator("#controller-state")).to_contain_text(f"ur_rtde at 127.0.0.1 ({ports})")
    # before anything is deployed, the page says what a deployment to this robot holds for
    expect(page.locator("#controller-scope")).to_contain_text(NEXT_START)
    page.click("#deploy-button")
    confirm = page.locator("#deploy-confirm")
    expect(confirm).to_contain_text(f"into the controller at 127.0.0.1 ({ports}) (ur_rtde)")
    expect(confirm).to_contain_text(NEXT_START)
    page.click("#deploy-yes")
    expect(page.locator("#deploy-outcome")).to_contain_text("Verified: tcp_offset holds version 1")
    expect(page.locator("#deploy-live")).to_contain_text(NEXT_START)
    cell.rig.assert_holds(GLUE["position_mm"], GLUE["quaternion"])
    # the deployment's scope, in its row of the table
    row = page.locator("#deployments tbody tr").first
    expect(row.locator("td.target")).to_have_text("tcp_offset (live)")
    expect(row.locator("td.target .scope")).to_have_attribute("title", re.compile(NEXT_START))
    expect(page.locator("#controller-state")).to_contain_text("in sync")

    # the robot's other tool: not the one it moves by, said in words
    _open(page, cell, f"/ui/tools/{cell.gripper_id}")
    expect(page.locator("#controller-state .badge")).to_have_text("not live")
    expect(page.locator("#controller-not-live")).to_contain_text(
        "Not live: the robot has one live TCP, and this tool is not the one deployed to it last: "
        "deploy this one to make it the live one."
    )
    _open(page, cell, "/ui/")
    fleet = page.locator("#fleet tbody")
    glue = fleet.locator(f"tr[data-tool-id='{cell.glue_id}'] td.controller-state")
    gripper = fleet.locator(f"tr[data-tool-id='{cell.gripper_id}'] td.controller-state")
    expect(glue).to_have_text("in sync")
    expect(gripper).to_have_text("not live")
    expect(gripper.locator(".badge")).to_have_attribute(
        "title", re.compile("this tool is not the one deployed to it last")
    )

    # a program is played: it starts with the installation's TCP, not the deployed one
    cell.rig.sim.play_program()
    with cell.server.client() as http:
        reconciled = http.post(f"/v1/robots/{cell.robot_id}/reconcile").json()
    assert reconciled["state"] == "drifted", reconciled
    _open(page, cell, f"/ui/tools/{cell.glue_id}")
    expect(page.locator("#controller-state .badge")).to_contain_text("drifted")
    expect(page.locator("#controller-scope")).to_contain_text(NEXT_START)
