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
    # Each touch is drawn (the next role asked for) before the next is typed, as a person
    # reads the next role first: a touch sent before it is refused by the page (the buttons
    # are off while one is on its way), which would take it in the last role asked for.
    asked = (
        "Next: touch a point on the frame's +X axis, at least 82 mm from the origin touch",
        "Next: touch a point in the frame's XY plane, on the +Y side of the X axis, at least"
        " 82 mm from the X axis",
    )
    for point, then in zip((ORIGIN, X_TOUCH), asked, strict=True):
        page.keyboard.press("Tab")  # from Capture to the typed pose
        page.keyboard.type(typed(point))
        page.keyboard.press("Enter")
        expect(next_role).to_have_text(then)
        expect(page.locator("#capture")).to_be_enabled()
        page.locator("#capture").focus()
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


def _tab_to(page: Page, selector: str, most: int = 12) -> None:
    """Press Tab until the element of `selector` has the focus (as a keyboard reaches it)."""
    target = page.locator(selector)
    for _ in range(most):
        if target.evaluate("el => el === document.activeElement"):
            return
        page.keyboard.press("Tab")
    expect(target).to_be_focused()


def test_fit_points_chosen_by_keyboard_takes_a_nominal_per_touch_and_deletes_a_wrong_one(
    page: Page, console_server: LiveServer
) -> None:
    """The method is chosen among the frame methods of the frame's kind (GET /v1/methods);
    fit_points asks each touch's point in the frame; a wrongly taken touch is deleted (DELETE
    /v1/sessions/{id}/poses/{index}) and taken again before Finish, all by keyboard."""
    expect.set_options(timeout=20_000)
    frame, _pointer = base_to_teach(console_server, "kr16-fit")
    page.set_viewport_size({"width": 768, "height": 1024})
    sign_in_to(page, console_server, f"/ui/frames/{frame['id']}/calibrate")
    method = page.locator("select[name=method]")
    expect(method.locator("option")).to_have_text(["three_point", "four_point", "fit_points"])
    method.focus()
    page.keyboard.type("fi")  # a focused select's type-ahead
    expect(method).to_have_value("fit_points")
    _tab_to(page, "#frame-start button[type=submit]")
    page.keyboard.press("Enter")
    busy = page.locator("main")
    nominal = page.locator("#nominal")
    expect(nominal).to_be_focused()
    touches = page.locator("#frame-touches li")
    wrong = ("0 200 0", X_TOUCH)  # the +X point touched where the pin P3 was asked
    third = ORIGIN + np.array([0.0, 200.0, 0.0])

    def touch(at: str, point: np.ndarray) -> None:
        """The nominal point typed, then the touch's pose, sent; back to the nominal field."""
        expect(nominal).to_be_focused()
        page.keyboard.type(at)
        _tab_to(page, "input[name=pose]")
        page.keyboard.type(typed(point))
        page.keyboard.press("Enter")
        expect(busy).to_have_attribute("aria-busy", "false")
        expect(page.locator("input[name=pose]")).to_have_value("")
        page.keyboard.press("Shift+Tab")  # back over Capture to the nominal field
        page.keyboard.press("Shift+Tab")

    for at, point in [("0 0 0", ORIGIN), ("300 0 0", X_TOUCH), wrong]:
        touch(at, point)
    expect(touches.nth(2)).to_contain_text("at 0 200 0 (typed): 1200.000  100.000  300.000 mm")
    _tab_to(page, "[aria-label='Delete touch 3']", most=20)
    page.keyboard.press("Enter")
    expect(busy).to_have_attribute("aria-busy", "false")
    expect(touches.filter(has_text="(typed)")).to_have_count(2)
    expect(nominal).to_be_focused()
    for at, point in [("0 200 0", third), ("150 100 40", ORIGIN + np.array([150.0, 100.0, 40.0]))]:
        touch(at, point)
    expect(touches.nth(2)).to_contain_text("at 0 200 0 (typed): 900.000  300.000  300.000 mm")
    _tab_to(page, "#finish")
    page.keyboard.press("Enter")
    result = page.locator("#frame-result")
    expect(result.locator("h2")).to_have_text("Frame v1: accepted")
    expect(result.locator("#frame-origin")).to_contain_text("Origin 900.000  100.000  300.000 mm")
    expect.set_options(timeout=5_000)
