"""The calibrate page (/ui/tools/{id}/calibrate, contract v1.3) in a real Chromium, against a
KUKAVARPROXY simulator in this process and a live server: Capture adds a touch, the next
suggested touch is shown in the robot's format and in words, a moving robot's refusal is
explained, typed touches and their outliers, Finish shows the report, Activate and Deploy
work from there, and all of it by keyboard alone. Then the fleet and tool pages say which TCP
the robot moves by.

The KRC moves by an old guess of the tool ($ACT_TOOL 3) in a shifted, turned $BASE, so what
it prints is neither the flange nor in the robot's base frame (as tests/api/test_capture_kuka).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Page, expect
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_from_format, pose_to_format
from testbed.live_server import LiveServer, fresh_database, live_server
from tests.api.controller_rigs import SLOT, TIMEOUT_S, Rig, rig
from tests.browser.conftest import sign_in_to
from tests.browser.test_console_tool_page import CUT_OFF

pytestmark = [pytest.mark.live, pytest.mark.browser]

TRUE_TCP = np.array([12.5, -7.25, 182.0])
POINT = np.array([850.0, -120.0, 240.0])
#: The KRC's tool data and $BASE while the touches are taken (mm, deg).
OLD_GUESS = (4.0, -2.5, 170.0, 10.0, -5.0, 3.0)
BASE = (1200.0, -400.0, 50.0, 25.0, -3.0, 1.5)
#: The first touch: the tool pointing down, turned a little.
FIRST = Rotation.from_euler("ZYX", [20.0, 5.0, 180.0], degrees=True)
_names = itertools.count(1)


@dataclass
class Cell:
    server: LiveServer
    rig: Rig


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("console-calibrate")
    with (
        rig("kuka_kvp") as r,
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
    ):
        yield Cell(server, r)


@pytest.fixture(scope="module", autouse=True)
def patient() -> Iterator[None]:
    """Each capture is two controller reads 100 ms apart and a solve, the report loads Plotly:
    on a loaded 2-core machine that took more than Playwright's 5 s once. 20 s, this module."""
    expect.set_options(timeout=20_000)
    yield
    expect.set_options(timeout=5_000)


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return cell.server


@pytest.fixture
def krc(cell: Cell) -> Iterator[Rig]:
    """The KRC as a test finds it: the old guess in SLOT selected, $BASE set, standing still."""
    r = cell.rig
    r.sim.set_tool(SLOT, *OLD_GUESS)
    r.sim.select_tool(SLOT)
    r.sim.set_base(*BASE)
    r.sim.moving_per_read = 0.0
    yield r
    r.sim.moving_per_read = 0.0


def _torch(cell: Cell, *, controller: bool = True) -> dict[str, Any]:
    """A new robot (on the simulator's controller, or none) with a tool in SLOT whose v1 is
    the old guess, active."""
    with cell.server.client() as http:
        robot = http.post("/v1/robots", json={"name": f"kr16-{next(_names)}"}).json()
        if controller:
            http.put(
                f"/v1/robots/{robot['id']}/controller", json=cell.rig.controller_body()
            ).raise_for_status()
        tool = http.post(
            f"/v1/robots/{robot['id']}/tools", json={"name": "torch", "slot": SLOT}
        ).json()
        body = {"method": "manual", "format": "kuka_abc", "poses": [list(OLD_GUESS)]}
        http.post(f"/v1/tools/{tool['id']}/calibrations", json=body).raise_for_status()
        return dict(tool)


def _session(cell: Cell, tool_id: str) -> dict[str, Any]:
    with cell.server.client() as http:
        items = http.get(f"/v1/tools/{tool_id}/sessions").json()["items"]
    return dict(items[0])


def _stand_at(r: Rig, rotation: Rotation) -> None:
    """Jog so the true TCP touches the point at this orientation."""
    r.sim.set_flange(tuple(POINT - rotation.apply(TRUE_TCP)), rotation.as_matrix())


def _suggested(session: dict[str, Any]) -> Rotation:
    rotation, _ = pose_from_format("kuka_abc", session["next_pose"])
    return Rotation.from_matrix(np.asarray(rotation))


def _shows_the_suggestion(page: Page, state: dict[str, Any]) -> None:
    """The next pose in KUKA's X Y Z A B C, and in words: its tilt, lean and spin from the
    first touch as the session computed them."""
    pose, words = state["next_pose"], state["next_touch"]
    shown = "  ".join(f"{name} {value:.3f}" for name, value in zip("XYZABC", pose, strict=True))
    expect(page.locator("#next-pose")).to_have_text(shown)
    said = page.locator("#next-words")
    expect(said).to_contain_text(f"tilt the tool axis {words['tilt_deg']:.1f}° from touch 1's")
    expect(said).to_contain_text(f"({words['lean_deg']:.0f}° from +x)")
    spin = words["spin_deg"]
    sign = "+" if spin >= 0 else "−"
    expect(said).to_contain_text(
        "no spin about it" if abs(spin) < 0.05 else f"spin {sign}{abs(spin):.1f}° about"
    )


def _touches(page: Page) -> Any:
    return page.locator("#touches tbody tr")


def test_capture_guides_to_done_then_finish_activate_and_deploy(
    page: Page, cell: Cell, krc: Rig
) -> None:
    tool = _torch(cell)
    sign_in_to(page, cell.server, f"/ui/tools/{tool['id']}")
    page.click("#calibrate-link")  # reachable from the tool page
    expect(page.locator("#session-format")).to_have_value("kuka_abc")  # the robot's own
    page.click("#start")
    expect(page.locator("#capture")).to_be_focused()

    _stand_at(krc, FIRST)
    page.click("#capture")
    expect(_touches(page)).to_have_count(1)
    expect(_touches(page).first).to_have_attribute("data-source", "controller")
    expect(_touches(page).first).to_contain_text("captured")
    state = _session(cell, tool["id"])
    # the pose kept is the flange the KRC stood at, whatever tool and base it moves by
    rotation, flange = pose_from_format("kuka_abc", state["poses"][0])
    assert np.allclose(flange, POINT - FIRST.apply(TRUE_TCP), atol=1e-3)
    off = FIRST.inv() * Rotation.from_matrix(np.asarray(rotation))
    assert np.degrees(off.magnitude()) < 1e-3
    _shows_the_suggestion(page, state)

    # a moving robot: refused, explained, nothing kept
    krc.sim.moving_per_read = 0.5
    page.click("#capture")
    problem = page.locator("#touch-problem")
    expect(problem).to_contain_text("The robot was moving: nothing was kept.")
    expect(problem).to_contain_text("come to rest")
    expect(_touches(page)).to_have_count(1)
    assert _session(cell, tool["id"])["n_poses"] == 1
    krc.sim.moving_per_read = 0.0

    # follow the suggestions until done
    spins = []
    for n in range(2, 13):
        state = _session(cell, tool["id"])
        if state["done"]:
            break
        _shows_the_suggestion(page, state)
        spins.append(state["next_touch"]["spin_deg"])
        _stand_at(krc, _suggested(state))
        page.click("#capture")
        expect(_touches(page)).to_have_count(n)
        expect(page.locator("#touch-problem")).to_have_count(0)
    state = _session(cell, tool["id"])
    assert state["done"], state["messages"]
    assert max(map(abs, spins)) > 1.0, spins  # the words said a spin at least once
    expect(page.locator("#done")).to_contain_text("Done: the TCP is known to")
    expect(page.locator("#next-touch")).to_have_count(0)
    residual = _touches(page).nth(1).locator("td.residual")
    expect(residual).to_have_text(f"{state['residuals_mm'][1]:.3f}")
    sigma = ", ".join(f"{v:.3f}" for v in state["estimate"]["tcp_sigma_mm"])
    expect(page.locator("#estimate [data-field=tcp_sigma_mm]")).to_have_text(f"± {sigma}")

    page.click("#finish")
    summary = page.locator("#finished-summary")
    expect(summary).to_be_visible()
    with cell.server.client() as http:
        cal = http.get(f"/v1/calibrations/{_session(cell, tool['id'])['calibration_id']}").json()
    assert np.linalg.norm(np.subtract(cal["tcp"]["position_mm"], TRUE_TCP)) <= 0.01
    assert cal["version"] == 2
    assert not cal["active"]  # the page asks before anything goes live
    expect(summary).to_have_text(cal["summary"])
    expect(page.locator("#report-link")).to_have_attribute("href", f"/ui/calibrations/{cal['id']}")

    page.click("#activate-new")
    page.locator("dialog#confirm textarea[name=reason]").fill("calibrated at the cell")
    page.locator("dialog#confirm button[type=submit]").click()
    expect(page.locator("#activated")).to_contain_text("Version 2 is active")
    page.click("#deploy-new")
    expect(page.locator("#deployed")).to_contain_text("Verified: $TOOL_DATA[3] holds version 2")
    krc.assert_holds(cal["tcp"]["position_mm"], cal["tcp"]["quaternion"])

    page.click("#report-link")
    expect(page.locator("#summary")).to_have_text(cal["summary"])


def _type_pose(page: Page, pose: list[float]) -> None:
    for name, value in zip("XYZABC", pose, strict=True):
        page.fill(f"#pose-{name}", f"{value:.6f}")
    page.click("#add-typed")


def _typed(rotation: Rotation, miss_mm: float = 0.0) -> list[float]:
    flange = POINT - rotation.apply(TRUE_TCP) + np.array([miss_mm, 0.0, 0.0])
    pose = pose_to_format("kuka_abc", rotation.as_matrix(), flange)
    return [float(v) for v in pose if isinstance(v, float)]


def test_typed_touches_an_outlier_marked_deleted_and_a_session_resumed(
    page: Page, cell: Cell
) -> None:
    """Without a controller: no Capture, the pose typed in the robot's format; a 3 mm miss is
    marked an outlier with its residual, numbered from 1, and deleted; a reload resumes."""
    tool = _torch(cell, controller=False)
    sign_in_to(page, cell.server, f"/ui/tools/{tool['id']}/calibrate")
    page.select_option("#session-format", "kuka_abc")
    page.click("#start")
    expect(page.locator("#no-capture")).to_be_visible()
    expect(page.locator("#capture")).to_have_count(0)
    _type_pose(page, _typed(FIRST))
    expect(_touches(page)).to_have_count(1)
    for n in range(2, 7):
        rotation = _suggested(_session(cell, tool["id"]))
        _type_pose(page, _typed(rotation, miss_mm=3.0 if n == 3 else 0.0))
        expect(_touches(page)).to_have_count(n)
    state = _session(cell, tool["id"])
    assert state["outliers"] == [2], state["messages"]
    third = _touches(page).nth(2)
    expect(third).to_have_class("outlier")
    expect(third.locator("td").first).to_have_text("3")
    expect(third).to_have_attribute("data-source", "typed")
    expect(third.locator("td.residual")).to_have_text(f"{state['residuals_mm'][2]:.3f}")
    expect(page.locator("#messages")).to_contain_text("touch 3 (index 2)")
    page.reload()
    expect(page.locator("#resumed")).to_contain_text("Resumed the open session")
    expect(_touches(page)).to_have_count(6)
    page.click("#touches tbody tr:nth-child(3) button.delete")
    expect(_touches(page)).to_have_count(5)
    expect(page.locator("#touches tr.outlier")).to_have_count(0)
    assert _session(cell, tool["id"])["n_poses"] == 5
    # six numbers pasted into the first field (from a pendant's screen) fill all six
    page.evaluate(
        """(text) => {
            const data = new DataTransfer();
            data.setData("text/plain", text);
            const init = { clipboardData: data, bubbles: true, cancelable: true };
            const paste = new ClipboardEvent("paste", init);
            document.getElementById("pose-X").dispatchEvent(paste);
        }""",
        "X 812.5, Y -120.25, Z 300, A 20, B 5.5, C -179.75",
    )
    values = [page.input_value(f"#pose-{name}") for name in "XYZABC"]
    assert values == ["812.5", "-120.25", "300", "20", "5.5", "-179.75"]
    # a field that is not a number is refused on the page, nothing sent
    for name, value in zip("XYZABC", ["812,5", "x", "1", "2", "3", "4"], strict=True):
        page.fill(f"#pose-{name}", value)
    page.click("#add-typed")
    expect(page.locator("#touch-problem")).to_contain_text("one number")
    assert _session(cell, tool["id"])["n_poses"] == 5


@pytest.mark.parametrize(("width", "height"), [(1400, 900), (768, 1024)])
def test_the_calibrate_page_fits_a_tablet_and_a_desktop(
    page: Page, cell: Cell, krc: Rig, width: int, height: int
) -> None:
    """Six touches (one an outlier), the estimate and the next touch: nothing wider than the
    window, nothing cut, and the six pose fields in one row."""
    tool = _torch(cell)
    with cell.server.client() as http:
        body = {"method": "xyz_npoint", "format": "kuka_abc", "target_sigma_mm": 0.001}
        sid = http.post(f"/v1/tools/{tool['id']}/sessions", json=body).json()["id"]
        rotation = FIRST
        for n in range(6):
            pose = _typed(rotation, miss_mm=3.0 if n == 2 else 0.0)
            state = http.post(f"/v1/sessions/{sid}/poses", json={"pose": pose}).json()
            rotation = _suggested(state)
    assert state["outliers"] == [2]
    page.set_viewport_size({"width": width, "height": height})
    sign_in_to(page, cell.server, f"/ui/tools/{tool['id']}/calibrate")
    expect(_touches(page)).to_have_count(6)
    expect(page.locator("#next-pose")).to_be_visible()
    scroll, client = page.evaluate(
        "[document.documentElement.scrollWidth, document.documentElement.clientWidth]"
    )
    assert scroll <= client, f"{scroll} px wide in a {client} px window"
    assert page.evaluate(CUT_OFF) == []
    boxes = [page.locator(f"#pose-{name}").bounding_box() for name in "XYZABC"]
    tops = [box["y"] for box in boxes if box is not None]
    assert len(tops) == 6
    assert len(set(tops)) == 1, tops  # one row


def _tab_to(page: Page, selector: str, limit: int = 80) -> None:
    """Press Tab until the element `selector` has the focus."""
    for _ in range(limit):
        if page.evaluate("(s) => document.activeElement?.matches(s) ?? false", selector):
            return
        page.keyboard.press("Tab")
    raise AssertionError(f"Tab never reached {selector}")


def test_keyboard_alone_starts_captures_types_finishes_activates_and_deploys(
    page: Page, cell: Cell, krc: Rig
) -> None:
    tool = _torch(cell)
    sign_in_to(page, cell.server, f"/ui/tools/{tool['id']}")
    _tab_to(page, "#calibrate-link")
    page.keyboard.press("Enter")
    expect(page.locator("#start")).to_be_focused()
    page.keyboard.press("Enter")
    expect(page.locator("#capture")).to_be_focused()
    _stand_at(krc, FIRST)
    page.keyboard.press("Enter")
    expect(_touches(page)).to_have_count(1)
    for n in range(2, 6):
        # four tilts 30 deg each way, spun: without noise the TCP is known at 4 touches and
        # the session stops suggesting, so these are not its suggestions
        rotation = FIRST * Rotation.from_euler("zx", [90.0 * n, 30.0], degrees=True)
        if n % 2:  # captured
            expect(page.locator("#capture")).to_be_focused()
            _stand_at(krc, rotation)
            page.keyboard.press("Enter")
        else:  # typed: Tab into the first field, type, Tab on, Enter submits
            _tab_to(page, "#pose-X")
            for value in _typed(rotation):
                page.keyboard.type(f"{value:.6f}")
                page.keyboard.press("Tab")
            expect(page.locator("#add-typed")).to_be_focused()
            page.keyboard.press("Enter")
            expect(page.locator("#pose-X")).to_be_focused()
            _tab_to(page, "#capture")  # Shift-less: Tab wraps round the page
        expect(_touches(page)).to_have_count(n)
    sources = [t["source"] for t in _session(cell, tool["id"])["touches"]]
    assert sources == ["controller", "typed", "controller", "typed", "controller"]
    _tab_to(page, "#finish")
    page.keyboard.press("Enter")
    expect(page.locator("#activate-new")).to_be_focused()
    page.keyboard.press("Enter")
    expect(page.locator("dialog#confirm textarea[name=reason]")).to_be_focused()
    page.keyboard.type("keyboard only")
    page.keyboard.press("Tab")
    page.keyboard.press("Enter")
    expect(page.locator("#activated")).to_contain_text("Version 2 is active")
    expect(page.locator("#deploy-new")).to_be_focused()
    page.keyboard.press("Enter")
    expect(page.locator("#deployed")).to_contain_text("holds version 2")


def test_the_fleet_and_tool_pages_say_which_tcp_the_robot_moves_by(
    page: Page, cell: Cell, krc: Rig
) -> None:
    """v1 the old guess, v2 a manual TCP, active; the KRC's $TOOL set to each, then to a frame
    no version has; a reconcile round reads it."""
    tool = _torch(cell)
    v2 = [12.5, -7.25, 182.0, 0.0, 0.0, 0.0]
    with cell.server.client() as http:
        body = {"method": "manual", "format": "kuka_abc", "poses": [v2], "activate": "always"}
        http.post(f"/v1/tools/{tool['id']}/calibrations", json=body).raise_for_status()

    sign_in_to(page, cell.server, "/ui/")

    def seen(frame: tuple[float, ...], fleet: str, tool_page: str, state: str) -> None:
        krc.sim.set_tool_frame(*frame)
        with cell.server.client() as http:
            http.post(f"/v1/robots/{tool['robot_id']}/reconcile").raise_for_status()
        page.goto(f"{cell.server.url}/ui/")
        cell_ = page.locator(f"#fleet tbody tr[data-tool-id='{tool['id']}'] td.live-state")
        expect(cell_).to_have_text(fleet)
        expect(cell_).to_have_attribute("data-state", state)
        page.goto(f"{cell.server.url}/ui/tools/{tool['id']}")
        expect(page.locator("#live-tool")).to_contain_text(tool_page)

    seen(tuple(v2), "moving by torch v2, active", "moving by torch v2, active", "active")
    seen(OLD_GUESS, "moving by torch v1: not the active v2", "not the active v2", "stale_version")
    elsewhere = (40.0, 40.0, 300.0, 0.0, 0.0, 0.0)
    seen(elsewhere, "moving by a TCP no version has", "a TCP no version has", "unknown")
    gripper = (0.0, 35.0, 120.0, 90.0, 0.0, 0.0)
    with cell.server.client() as http:
        other = http.post(
            f"/v1/robots/{tool['robot_id']}/tools", json={"name": "gripper", "slot": SLOT + 1}
        ).json()
        body = {"method": "manual", "format": "kuka_abc", "poses": [list(gripper)]}
        http.post(f"/v1/tools/{other['id']}/calibrations", json=body).raise_for_status()
    seen(gripper, "moving by gripper v1, not torch", "gripper v1, not torch", "other_tool")


def test_a_controller_that_does_not_answer_is_said_and_nothing_kept(
    page: Page, cell: Cell, krc: Rig
) -> None:
    """Capture on a stalled KRC: the 502 with the server's words (what was tried, that nothing
    was kept), within the connection's timeout_s + 1 s, and the session unchanged."""
    tool = _torch(cell)
    sign_in_to(page, cell.server, f"/ui/tools/{tool['id']}/calibrate")
    page.click("#start")
    krc.sim.stalled = True
    try:
        started = time.monotonic()
        page.click("#capture")
        problem = page.locator("#touch-problem")
        expect(problem).to_contain_text("502")
        took = time.monotonic() - started
        # the KRC took the connection and went silent: said so since 61b50e3 (defect 8)
        expect(problem).to_contain_text("accepted the TCP connection and sent nothing within 1 s")
        expect(problem).to_contain_text("nothing was kept")
    finally:
        krc.sim.stalled = False
    assert took <= TIMEOUT_S + 1.0, took
    expect(_touches(page)).to_have_count(0)
    assert _session(cell, tool["id"])["n_poses"] == 0
    expect(page.locator("#capture")).to_be_focused()  # press again once it answers


def test_a_read_key_is_told_calibrating_needs_calibrate_scope(page: Page, cell: Cell) -> None:
    tool = _torch(cell, controller=False)
    with cell.server.client() as http:
        made = http.post("/v1/keys", json={"name": f"reader-{next(_names)}", "scope": "read"})
        made.raise_for_status()
    sign_in_to(page, cell.server, f"/ui/tools/{tool['id']}", key=made.json()["key"])
    expect(page.locator("#calibrate-link")).to_have_count(0)
    page.goto(f"{cell.server.url}/ui/tools/{tool['id']}/calibrate")
    expect(page.locator("#needs-calibrate")).to_contain_text("a key of calibrate scope")
    expect(page.locator("#start")).to_have_count(0)
