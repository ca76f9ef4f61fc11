"""The frame page's "re-check after a move" (issue 49, API.md v1.4 "After a move:
re-register") in a real Chromium against a live server and a KUKAVARPROXY simulator, at a
tablet's size: a base taught from three touches is touched again at its stored fiducials
(typed as a pendant shows them), and the page says what a person needs: each fiducial's
deviation, the shift, and what became of the frame. Moved 8 mm it is refused and nothing
changes; moved 1.5 mm it is corrected to v2, deployed and read back from BASE_DATA[2]."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.api.controller_rigs import Rig, rig
from tests.browser.conftest import sign_in_to
from tests.live_frames import ORIGIN, X_TOUCH, XY_TOUCH, base_to_teach, typed

pytestmark = [pytest.mark.live, pytest.mark.browser]

#: The base's stored fiducials (its three-point touches' roles) and where they were.
FIDUCIALS = {"origin": ORIGIN, "x": X_TOUCH, "xy": XY_TOUCH}


@dataclass
class Cell:
    server: LiveServer
    rig: Rig
    frame_id: str


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    """A KUKA robot on the simulator, its base 2 taught from three typed touches (v1)."""
    tmp = tmp_path_factory.mktemp("console-frame-recheck")
    with (
        rig("kuka_kvp") as r,
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
    ):
        frame, pointer = base_to_teach(server)
        with server.client() as http:
            http.put(
                f"/v1/robots/{frame['robot_id']}/controller", json=r.controller_body()
            ).raise_for_status()
            taught = {
                "method": "three_point",
                "tool_id": pointer["id"],
                "format": "kuka_abc",
                "touches": [
                    {"role": role, "pose": [float(v) for v in typed(p).split()]}
                    for role, p in FIDUCIALS.items()
                ],
            }
            http.post(f"/v1/frames/{frame['id']}/calibrations", json=taught).raise_for_status()
            names = [
                f["name"] for f in http.get(f"/v1/frames/{frame['id']}/fiducials").json()["items"]
            ]
            assert names == list(FIDUCIALS), names
        yield Cell(server, r, frame["id"])


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return cell.server


def _recheck(page: Page, cell: Cell, moved_mm: float, reason: str) -> None:
    """Open the frame page, start a re-check (correct within limits) and type each stored
    fiducial touched again with the fixture moved `moved_mm` along the base's X, then finish."""
    page.set_viewport_size({"width": 768, "height": 1024})  # a tablet, upright
    sign_in_to(page, cell.server, f"/ui/frames/{cell.frame_id}/calibrate")
    section = page.locator("#recheck-frame")
    expect(section.locator("h2")).to_have_text("Re-check after a move")
    expect(section).to_contain_text("at least 3 of origin, x, xy")
    expect(section.locator("input[name=correct]")).to_be_checked()
    section.locator("input[name=reason]").fill(reason)
    section.locator("button[type=submit]").click()
    next_role = page.locator("#next-role")
    expect(next_role).to_have_text("Next: touch fiducial 'origin' again")
    for name, point in FIDUCIALS.items():
        expect(next_role).to_contain_text(f"fiducial '{name}'")
        page.locator("input[name=pose]").fill(typed(point + np.array([moved_mm, 0.0, 0.0])))
        page.locator("input[name=pose]").press("Enter")
    expect(next_role).to_have_text("Every fiducial touched: finish to check the frame.")
    touches = page.locator("#frame-touches li")
    expect(touches.nth(0)).to_contain_text("origin (typed)")
    expect(touches.nth(2)).to_contain_text("xy (typed)")
    page.locator("#finish").click()


def test_a_fixture_moved_8_mm_is_refused_and_the_page_says_nothing_changed(
    page: Page, cell: Cell
) -> None:
    expect.set_options(timeout=20_000)
    held = cell.rig.sim.base_data(2)
    _recheck(page, cell, 8.0, "bumped by the forklift")
    result = page.locator("#frame-result")
    expect(result.locator("#check-outcome")).to_have_text(
        "Not corrected: nothing changed (v1 stays active)"
    )
    expect(result.locator("#check-deviations li")).to_have_count(3)
    expect(result.locator("#check-deviations li").first).to_contain_text(
        "fiducial 'origin' moved 8.00 mm (+8.00 x"
    )
    expect(result.locator("#check-shift")).to_contain_text("Shift: +8.000  +0.000  +0.000 mm")
    expect(result.locator("#frame-summary")).to_contain_text("beyond max_correction_mm")
    expect(result.locator("#frame-summary")).to_contain_text("nothing was changed")
    assert cell.rig.sim.base_data(2) == held
    expect.set_options(timeout=5_000)


def test_a_fixture_moved_1_5_mm_is_corrected_deployed_and_said(page: Page, cell: Cell) -> None:
    expect.set_options(timeout=20_000)
    _recheck(page, cell, 1.5, "unbolted for cleaning")
    result = page.locator("#frame-result")
    expect(result.locator("#check-outcome")).to_have_text(
        "Corrected to v2 (was v1), active; deployed to BASE_DATA[2] and read back as written "
        "(verified)"
    )
    deviations = result.locator("#check-deviations li")
    for i, name in enumerate(FIDUCIALS):
        expect(deviations.nth(i)).to_contain_text(f"fiducial '{name}' moved 1.50 mm (+1.50 x")
    expect(result.locator("#check-shift")).to_contain_text("Shift: +1.500  +0.000  +0.000 mm")
    expect(result.locator("#check-shift")).to_contain_text("(1.500 mm) and 0.000 deg")
    # the controller section drawn again: the new version deployed and in the history
    expect(page.locator("#controller-slot")).to_contain_text("v2")
    x, y, z = cell.rig.sim.base_data(2)[:3]
    np.testing.assert_allclose((x, y, z), ORIGIN + np.array([1.5, 0.0, 0.0]), atol=1e-3)
    expect.set_options(timeout=5_000)
