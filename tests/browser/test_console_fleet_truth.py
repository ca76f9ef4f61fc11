"""What the fleet page and a report say must be true and fit (issue 51), in a real Chromium:
a controller state read before the active version changed names the version it compared and
when; a re-check that corrected the tool is a correction, not a red "fail"; a robot at its
bare flange has no tool selected; the fleet fits a 768 px tablet without sideways scrolling;
narrowing a report from 1400 to 768 px leaves its plots apart; one version's "TCP over the
versions" axis has distinct ticks.

A live server (SQLite, one worker) and two KUKAVARPROXY simulators in this process."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest
from playwright.sync_api import FloatRect, Locator, Page, expect

from app.kinematics.poses import pose_to_format
from testbed.live_server import LiveServer, fresh_database, live_server
from testbed.sim.touches import simulate_touches
from tests.api.controller_rigs import rig
from tests.api.test_capture_controllers import SETUPS
from tests.api.test_recheck_controllers import (
    ACTIVE_POSITION,
    ACTIVE_Q,
    MOVED,
    REFERENCE,
    stand_at_reference,
)
from tests.browser.conftest import sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]


@dataclass
class Cell:
    server: LiveServer
    torch: str  # corrected by a re-check to v2, then v3 activated: the look compared v2
    idle: str  # a tool of a robot standing at its bare flange
    calibration: str  # a calibration with touches: residuals and the 3-D plot
    single: str  # a tool with one version, touched with 0.0005 mm noise


def _touches() -> list[list[float] | list[list[float]]]:
    touches = simulate_touches(
        8, seed=4, tcp_mm=np.array([12.5, -0.5, 150.0]), touch_noise_mm=0.0005,
        outlier_fraction=0.0,
    )  # fmt: skip
    return [pose_to_format("kuka_abc", r, f) for r, f in zip(touches.R, touches.f, strict=True)]


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("fleet-truth")
    with (
        rig("kuka_kvp") as r,
        rig("kuka_kvp") as idle_rig,
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
        server.client() as http,
    ):
        kuka = SETUPS["kuka_kvp"](r)
        robot = http.post("/v1/robots", json={"name": "kr16-weld-long-name", "cell": "weld-12"})
        robot_id = robot.json()["id"]
        http.put(f"/v1/robots/{robot_id}/controller", json=r.controller_body()).raise_for_status()
        tolerance = {"check_mm": 0.5, "max_correction_mm": 2.0}
        body = {"name": "torch", "slot": 3, "tolerance": tolerance}
        torch = http.post(f"/v1/robots/{robot_id}/tools", json=body).json()["id"]
        tcp = {"position_mm": ACTIVE_POSITION, "quaternion": ACTIVE_Q}
        http.post(
            f"/v1/tools/{torch}/calibrations", json={"method": "manual", "tcp": tcp}
        ).raise_for_status()
        http.post(f"/v1/tools/{torch}/deployments", json={}).raise_for_status()
        point = http.post(
            f"/v1/robots/{robot_id}/reference-points",
            json={"name": "pin", "position_mm": [float(v) for v in REFERENCE]},
        ).json()["id"]
        stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
        check = http.post(
            f"/v1/tools/{torch}/checks",
            json={"capture": True, "reference_point_id": point, "correct": "within_limits"},
        ).json()
        assert check["verdict"] == "corrected", check  # v2, deployed and read back
        http.post(f"/v1/robots/{robot_id}/reconcile").raise_for_status()  # v2 in sync
        moved = [ACTIVE_POSITION[0] + 0.3, *ACTIVE_POSITION[1:]]
        http.post(  # v3 active: nothing has compared the controller with it
            f"/v1/tools/{torch}/calibrations",
            json={"method": "manual", "tcp": {"position_mm": moved, "quaternion": ACTIVE_Q}},
        ).raise_for_status()
        single = http.post(f"/v1/robots/{robot_id}/tools", json={"name": "probe", "slot": 4})
        single_id = single.json()["id"]
        calibration = http.post(
            f"/v1/tools/{single_id}/calibrations",
            json={"method": "xyz_npoint", "format": "kuka_abc", "poses": _touches()},
        ).json()["id"]

        other = http.post("/v1/robots", json={"name": "kr6-handling", "cell": "assy-3"}).json()
        http.put(
            f"/v1/robots/{other['id']}/controller", json=idle_rig.controller_body()
        ).raise_for_status()
        idle = http.post(f"/v1/robots/{other['id']}/tools", json={"name": "gripper", "slot": 5})
        idle_id = idle.json()["id"]
        http.post(
            f"/v1/tools/{idle_id}/calibrations",
            json={"method": "manual", "tcp": {"position_mm": [0, 0, 120]}},
        ).raise_for_status()
        idle_rig.sim.set_tool_frame(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # $TOOL = $NULLFRAME
        http.post(f"/v1/robots/{other['id']}/reconcile").raise_for_status()
        yield Cell(server, torch, idle_id, calibration, single_id)


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    return cell.server


def _row(page: Page, tool_id: str) -> Locator:
    return page.locator(f"#fleet tbody tr[data-tool-id='{tool_id}']")


def test_a_state_read_before_the_activation_says_which_version_it_compared(
    page: Page, cell: Cell
) -> None:
    sign_in_to(page, cell.server, "/ui/")
    controller = _row(page, cell.torch).locator("td.controller-state")
    expect(controller).to_contain_text("v2 in sync at ")
    expect(controller).to_contain_text("v3 not compared yet")
    expect(controller.locator(".badge")).not_to_have_class("badge controller in_sync")


def test_a_check_that_corrected_the_tool_is_not_a_failed_check(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, "/ui/")
    check = _row(page, cell.torch).locator("td.last-check")
    expect(check).to_contain_text("corrected")
    expect(check).to_contain_text("→ v2")
    expect(check).not_to_contain_text("fail")
    assert check.locator(".badge.out_of_tolerance").count() == 0


def test_a_robot_at_its_bare_flange_has_no_tool_selected(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, "/ui/")
    row = _row(page, cell.idle)
    expect(row.locator("td.live-state")).to_have_text("at its bare flange: no tool selected")
    expect(row.locator("td.live-state")).to_have_attribute("data-state", "no_tool")
    expect(row.locator("td.reasons [data-code=moving_by_unknown_tcp]")).to_have_count(0)
    page.goto(f"{cell.server.url}/ui/tools/{cell.idle}")
    live = page.locator("#live-tool")
    expect(live).to_contain_text("The robot is at its bare flange: no tool selected")
    expect(live).not_to_have_class("attention")


@pytest.mark.parametrize("width", [768, 1024, 1400])
def test_the_fleet_fits_a_tablet_and_a_window(page: Page, cell: Cell, width: int) -> None:
    """Measured in the page: nothing wider than the viewport (a 768 px tablet scrolled the
    fleet sideways, 909-1202 px); every cell's label and text inside its row."""
    page.set_viewport_size({"width": width, "height": 1000})
    sign_in_to(page, cell.server, "/ui/")
    widths = page.evaluate(
        "() => ({doc: document.documentElement.scrollWidth,"
        " table: document.querySelector('#fleet').getBoundingClientRect().right,"
        " cells: Math.max(...[...document.querySelectorAll('#fleet td')]"
        ".map((td) => td.getBoundingClientRect().right))})"
    )
    assert max(widths.values()) <= width, widths


def _box(page: Page, selector: str) -> FloatRect:
    box = page.locator(selector).first.bounding_box()
    assert box is not None, selector
    return box


def _apart(a: FloatRect, b: FloatRect) -> bool:
    return (
        a["y"] + a["height"] <= b["y"]
        or b["y"] + b["height"] <= a["y"]
        or a["x"] + a["width"] <= b["x"]
        or b["x"] + b["width"] <= a["x"]
    )


def _sign_in_slowly(page: Page, server: LiveServer, path: str) -> None:
    """sign_in_to, waiting up to 30 s for the page's plots (software WebGL on a loaded
    machine draws a 3-D plot in seconds)."""
    page.goto(server.url + path)
    page.fill("input[name=api_key]", server.admin_key)
    page.click("#sign-in button[type=submit]")
    expect(page.locator("main")).to_have_attribute("aria-busy", "false", timeout=30_000)


def test_narrowing_a_report_keeps_its_plots_apart(page: Page, cell: Cell) -> None:
    _sign_in_slowly(page, cell.server, f"/ui/calibrations/{cell.calibration}")
    expect(page.locator("#plot-3d canvas").first).to_be_visible()
    page.set_viewport_size({"width": 768, "height": 1000})
    page.wait_for_timeout(1500)  # Plotly's responsive resize runs on the window's resize
    residuals = _box(page, "#plot-residuals .main-svg")
    for selector in ("#plot-3d canvas", "#plot-3d .main-svg"):
        for i in range(page.locator(selector).count()):
            box = page.locator(selector).nth(i).bounding_box()
            assert box is not None
            assert _apart(box, residuals), (selector, i, box, residuals)
    assert page.evaluate("document.documentElement.scrollWidth") <= 768


@pytest.mark.parametrize("which", ["single", "idle"])
def test_one_versions_tcp_axis_has_distinct_ticks(page: Page, cell: Cell, which: str) -> None:
    """One version, by touches (a sigma of hundredths of a mm) or typed in (no sigma)."""
    _sign_in_slowly(page, cell.server, f"/ui/tools/{getattr(cell, which)}")
    for axis in ("y", "y2", "y3"):
        ticks = page.locator(f"#plot-tcp .{axis}tick text").all_text_contents()
        assert len(ticks) >= 2, (axis, ticks)
        assert len(set(ticks)) == len(ticks), (axis, ticks)
