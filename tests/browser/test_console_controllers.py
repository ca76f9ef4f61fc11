"""The console's controller views in a real Chromium: the fleet's controller column, and on
a tool's page its state, the Deploy button (with its confirmation) and the deployments.

A live server (SQLite, one worker) and a KUKAVARPROXY simulator in this process."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.api.controller_rigs import Rig, rig
from tests.api.test_deployments import ACTIVE_POSITION, ACTIVE_Q
from tests.browser.conftest import sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]


@dataclass
class Cell:
    server: LiveServer
    rig: Rig
    robot_id: str
    tool_id: str


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("console-controllers")
    with (
        rig("kuka_kvp") as r,
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
        server.client() as http,
    ):
        robot = http.post("/v1/robots", json={"name": "kr16-weld", "cell": "weld-1"}).json()
        http.put(
            f"/v1/robots/{robot['id']}/controller", json=r.controller_body()
        ).raise_for_status()
        tool = http.post(
            f"/v1/robots/{robot['id']}/tools", json={"name": "torch", "slot": 3}
        ).json()
        body = {"method": "manual", "tcp": {"position_mm": ACTIVE_POSITION, "quaternion": ACTIVE_Q}}
        http.post(f"/v1/tools/{tool['id']}/calibrations", json=body).raise_for_status()
        yield Cell(server, r, robot["id"], tool["id"])


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return cell.server


def _sign_in(page: Page, cell: Cell, path: str) -> None:
    sign_in_to(page, cell.server, path)


def test_deploy_asks_first_then_shows_the_outcome_state_and_history(page: Page, cell: Cell) -> None:
    _sign_in(page, cell, f"/ui/tools/{cell.tool_id}")
    expect(page.locator("#controller-state")).to_contain_text("kuka_kvp at 127.0.0.1")
    expect(page.locator("#no-deployments")).to_be_visible()
    page.click("#deploy-button")
    confirm = page.locator("#deploy-confirm")
    expect(confirm).to_be_visible()
    expect(confirm).to_contain_text("Write version 1 of torch")
    page.click("#deploy-no")  # cancelled: nothing written
    expect(confirm).to_be_hidden()
    assert cell.rig.sim.tool(3) == (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    page.click("#deploy-button")
    page.click("#deploy-yes")
    expect(page.locator("#deploy-outcome")).to_contain_text(
        "Verified: $TOOL_DATA[3] holds version 1"
    )
    expect(page.locator("#deployments tbody tr")).to_have_count(1)
    expect(page.locator("#deployments tbody tr").first).to_contain_text("verified")
    expect(page.locator("#controller-state")).to_contain_text("in sync")
    cell.rig.assert_holds(ACTIVE_POSITION, ACTIVE_Q)

    # the controller switched off: the failure is explained and recorded
    cell.rig.sim.stalled = True
    try:
        page.click("#deploy-button")
        page.click("#deploy-yes")
        expect(page.locator("#deploy-outcome [role=alert]")).to_contain_text("502", timeout=10_000)
        expect(page.locator("#deployments tbody tr")).to_have_count(2)
        last = page.locator("#deployments tbody tr").first
        expect(last).to_have_attribute("data-status", "not_written")
        expect(last).to_contain_text("nothing was written: the controller still holds what it held")
    finally:
        cell.rig.sim.stalled = False


def test_the_fleet_shows_a_drifted_controller_as_needing_attention(page: Page, cell: Cell) -> None:
    moved = [ACTIVE_POSITION[0] + 0.25, *ACTIVE_POSITION[1:]]
    cell.rig.set_behind_back(moved, ACTIVE_Q)
    with cell.server.client() as http:
        assert http.post(f"/v1/robots/{cell.robot_id}/reconcile").json()["state"] == "drifted"
    _sign_in(page, cell, "/ui/")
    # A fleet of one tool says so in the singular (it said "1 tools, 1 need attention").
    expect(page.locator("#fleet-summary")).to_have_text("1 tool, 1 needs attention")
    row = page.locator(f"#fleet tbody tr[data-tool-id='{cell.tool_id}']")
    expect(row).to_have_class("attention")
    expect(row.locator("td.controller-state")).to_have_text("drifted 0.250 mm")
    expect(row.locator("td.reasons [data-code=controller_drifted]")).to_have_count(1)


def test_the_fleet_tells_an_orientation_only_drift_in_degrees(page: Page, cell: Cell) -> None:
    """Issue 37: turned 0.5 deg at the pendant, position kept, the fleet said "drifted
    0.000 mm", as if nothing had moved."""
    from scipy.spatial.transform import Rotation

    active = Rotation.from_quat(ACTIVE_Q, scalar_first=True)
    turned = active * Rotation.from_euler("x", 0.5, degrees=True)
    cell.rig.set_behind_back(ACTIVE_POSITION, list(turned.as_quat(scalar_first=True)))
    with cell.server.client() as http:
        assert http.post(f"/v1/robots/{cell.robot_id}/reconcile").json()["state"] == "drifted"
    _sign_in(page, cell, "/ui/")
    row = page.locator(f"#fleet tbody tr[data-tool-id='{cell.tool_id}']")
    expect(row.locator("td.controller-state")).to_have_text("drifted 0.000 mm, 0.500 deg")
