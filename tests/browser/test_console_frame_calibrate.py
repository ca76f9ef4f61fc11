"""The frame page (/ui/frames/{id}/calibrate, issue 47) in a real Chromium against a live
server, at a tablet's size and by keyboard alone: a base taught by three typed touches, the
next role said in the server's words (with how far the x touch must be), the touched points
and the frame's axes drawn in 3-D, and Finish showing the stored frame, its sigmas and
summary."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.browser.conftest import sign_in_to
from tests.live_frames import ORIGIN, X_TOUCH, XY_TOUCH, base_to_teach, typed

pytestmark = [pytest.mark.live, pytest.mark.browser]


@pytest.fixture(scope="module")
def console_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    tmp = tmp_path_factory.mktemp("console-frame")
    with fresh_database("sqlite", tmp, None) as url, live_server(url, workers=1, solvers=0) as srv:
        yield srv


def test_a_base_taught_by_keyboard_shows_its_touches_axes_and_result(
    page: Page, console_server: LiveServer
) -> None:
    expect.set_options(timeout=20_000)
    frame, _pointer = base_to_teach(console_server)
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
    for point in (ORIGIN, X_TOUCH):
        page.keyboard.press("Tab")  # from Capture to the typed pose
        page.keyboard.type(typed(point))
        page.keyboard.press("Enter")
        expect(page.locator("#frame-touches li").first).to_be_visible()
        page.locator("#capture").focus()
        if point is ORIGIN:
            expect(next_role).to_have_text(
                "Next: touch a point on the frame's +X axis, at least 82 mm from the origin touch"
            )
    page.locator("input[name=pose]").focus()
    page.keyboard.type(typed(XY_TOUCH))
    page.keyboard.press("Enter")
    expect(next_role).to_have_text("Done: finish to store the frame.")
    touches = page.locator("#frame-touches li")
    expect(touches.nth(0)).to_contain_text("origin (typed): 900.000  100.000  300.000 mm")
    expect(touches.nth(2)).to_contain_text("xy (typed)")
    expect(touches.nth(3)).to_have_text("the touches give a frame: finish to store it")
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
