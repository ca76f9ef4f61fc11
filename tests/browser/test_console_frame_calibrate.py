"""The frame page (/ui/frames/{id}/calibrate, issue 47) in a real Chromium against a live
server, at a tablet's size and by keyboard alone: a base taught by three typed touches, the
next role said in the server's words (with how far the x touch must be), the touched points
and the frame's axes drawn in 3-D, and Finish showing the stored frame, its sigmas and
summary."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from playwright.sync_api import Page, expect
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_to_format
from testbed.live_server import LiveServer, fresh_database, live_server
from tests.browser.conftest import sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]

TCP = np.array([0.0, 0.0, 150.0])
DOWN = Rotation.from_euler("x", 180, degrees=True)
ORIGIN = np.array([900.0, 100.0, 300.0])


@pytest.fixture(scope="module")
def console_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    tmp = tmp_path_factory.mktemp("console-frame")
    with fresh_database("sqlite", tmp, None) as url, live_server(url, workers=1, solvers=0) as srv:
        yield srv


def _typed(point: np.ndarray) -> str:
    flange = point - DOWN.apply(TCP)
    return " ".join(
        f"{v:.6f}" for v in np.ravel(pose_to_format("kuka_abc", DOWN.as_matrix(), flange))
    )


def test_a_base_taught_by_keyboard_shows_its_touches_axes_and_result(
    page: Page, console_server: LiveServer
) -> None:
    expect.set_options(timeout=20_000)
    with console_server.client() as http:
        robot = http.post("/v1/robots", json={"name": "kr16", "vendor": "KUKA"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "pointer"}).json()
        manual = {"method": "manual", "tcp": {"position_mm": TCP.tolist()}}
        assert http.post(f"/v1/tools/{tool['id']}/calibrations", json=manual).is_success
        frame = http.post(
            f"/v1/robots/{robot['id']}/frames",
            json={"name": "fixture-a", "kind": "base", "slot": 2,
                  "tolerance": {"touch_noise_mm": 0.05}},
        ).json()  # fmt: skip
    page.set_viewport_size({"width": 768, "height": 1024})  # a tablet, upright
    sign_in_to(page, console_server, f"/ui/frames/{frame['id']}/calibrate")
    expect(page.locator("h1")).to_contain_text("Teach fixture-a")
    page.locator("select[name=pointer]").focus()
    page.keyboard.press("Tab")  # the format, then the start button
    page.keyboard.press("Tab")
    page.keyboard.press("Enter")
    next_role = page.locator("#next-role")
    expect(next_role).to_have_text("Next: touch the frame's origin")
    expect(page.locator("#capture")).to_be_focused()
    for point in (ORIGIN, ORIGIN + np.array([300.0, 0.0, 0.0])):
        page.keyboard.press("Tab")  # from Capture to the typed pose
        page.keyboard.type(_typed(point))
        page.keyboard.press("Enter")
        expect(page.locator("#frame-touches li").first).to_be_visible()
        page.locator("#capture").focus()
        if point is ORIGIN:
            expect(next_role).to_have_text(
                "Next: touch a point on the frame's +X axis, at least 82 mm from the origin touch"
            )
    page.locator("input[name=pose]").focus()
    page.keyboard.type(_typed(ORIGIN + np.array([0.0, 200.0, 0.0])))
    page.keyboard.press("Enter")
    expect(next_role).to_have_text("Done: finish to store the frame.")
    touches = page.locator("#frame-touches li")
    expect(touches.nth(0)).to_contain_text("origin (typed): 900.000  100.000  300.000 mm")
    expect(touches.nth(2)).to_contain_text("xy (typed)")
    plot = page.locator("#frame-plot")
    expect(plot.locator(".legend")).to_contain_text("frame X")
    expect(plot.locator(".legend")).to_contain_text("touches")
    page.locator("#finish").focus()
    page.keyboard.press("Enter")
    result = page.locator("#frame-result")
    expect(result.locator("h2")).to_have_text("Frame v1: accepted")
    expect(result.locator("#frame-origin")).to_contain_text("Origin 900.000  100.000  300.000 mm")
    expect(result.locator("#frame-sigmas")).to_contain_text("1-sigma: position")
    expect(result.locator("#frame-summary")).not_to_be_empty()
    expect.set_options(timeout=5_000)
