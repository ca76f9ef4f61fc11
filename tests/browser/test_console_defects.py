"""What a new user tripped over in the console, each drawn in a real Chromium (issue 27):
a checks plot of one check (sub-millisecond axis, check_mm line of no length), three empty
panels for a tool without versions, "null" and "nullnull" in a manual calibration's report,
the 412 message drawn far from the button clicked, and "Age 1 h" for a two-minute-old
calibration."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from playwright.sync_api import Page, expect

from tests.browser.conftest import confirm, sign_in_to
from tests.live.server import LiveServer, fresh_database, http_client, live_server

pytestmark = [pytest.mark.live, pytest.mark.browser]


@dataclass
class Cell:
    server: LiveServer
    checked: str  # a tool with one version and one (failed) check
    bare: str  # a tool without versions
    manual: str  # the manual calibration of `checked`
    two: str  # a tool with two versions


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("defects")
    with fresh_database("sqlite", tmp, None) as url, live_server(url, workers=1) as server:
        with server.client() as http:
            robot = http.post("/v1/robots", json={"name": "r1", "cell": "c1"}).json()
            tools = [
                http.post(f"/v1/robots/{robot['id']}/tools", json={"name": n, "slot": i}).json()
                for i, n in enumerate(("checked", "bare", "two"), start=1)
            ]
            manual = http.post(
                f"/v1/tools/{tools[0]['id']}/calibrations",
                json={"method": "manual", "tcp": {"position_mm": [1, 2, 150]}},
            ).json()
            point = http.post(
                f"/v1/robots/{robot['id']}/reference-points",
                json={"name": "pin", "position_mm": [800, 0, 200]},
            ).json()
            http.post(  # 4 mm off: a failed check, drawn against check_mm = 1 mm
                f"/v1/tools/{tools[0]['id']}/checks",
                json={
                    "reference_point_id": point["id"],
                    "format": "kuka_abc",
                    "poses": [[799, -2, 350.2, 0, 0, 180]],
                },
            ).raise_for_status()
            for z in (150, 151):
                http.post(
                    f"/v1/tools/{tools[2]['id']}/calibrations",
                    json={"method": "manual", "tcp": {"position_mm": [0, 0, z]}},
                ).raise_for_status()
        yield Cell(server, tools[0]["id"], tools[1]["id"], manual["id"], tools[2]["id"])


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    return cell.server


def test_one_check_is_plotted_over_days_with_the_limit_line_drawn(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.checked}")
    expect(page.locator("#plot-checks g.trace.scatter")).to_have_count(2)
    ticks = page.locator("#plot-checks .xtick text").all_text_contents()
    assert ticks
    seconds = re.compile(r"\d:\d\d:\d\d")  # what a sub-day axis shows: 05:27:31.9075
    assert not [t for t in ticks if seconds.search(t)], ticks
    limit = page.locator("#plot-checks g.trace.scatter").nth(1).locator("path.js-line")
    box = limit.bounding_box()
    assert box is not None
    assert box["width"] > 300  # the check_mm line spans the plot (it had no length)
    top = float(page.locator("#plot-checks .ytick text").last.text_content() or "0")
    assert top >= 4.0  # the 4 mm check and the 1 mm line are both inside the axis
    # The TCP plot of the tool's one version is over days too.
    tcp_ticks = page.locator("#plot-tcp .xtick text").all_text_contents()
    assert tcp_ticks
    assert not [t for t in tcp_ticks if seconds.search(t)], tcp_ticks


def test_a_tool_without_versions_says_so_instead_of_three_empty_panels(
    page: Page, cell: Cell
) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.bare}")
    expect(page.locator("#no-versions")).to_contain_text("No versions yet")
    expect(page.locator("#plot-tcp")).to_have_count(0)


def test_a_manual_calibrations_report_shows_no_null(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/calibrations/{cell.manual}")
    expect(page.locator("#figures")).to_be_visible()
    text = page.locator("main").inner_text()
    assert "null" not in text.replace('"null"', "")  # it showed null and nullnull
    expect(page.locator("[data-field=tcp_mm]")).to_have_text("1.000, 2.000, 150.000")


def test_a_stale_page_explains_itself_beside_the_button_clicked(page: Page, cell: Cell) -> None:
    page.set_viewport_size({"width": 1200, "height": 700})
    sign_in_to(page, cell.server, f"/ui/tools/{cell.two}")
    button = page.locator("#versions tr[data-version='1'] button")
    expect(button).to_be_visible()
    auth = {"Authorization": f"Bearer {cell.server.admin_key}"}
    with http_client(cell.server.url, headers=auth) as http:
        http.post(f"/v1/tools/{cell.two}/versions/1/activate").raise_for_status()
        http.post(f"/v1/tools/{cell.two}/versions/2/activate").raise_for_status()
    button.click()
    confirm(page, "back to version 1")
    alert = page.get_by_role("alert")
    expect(alert).to_contain_text("this page is out of date")
    expect(alert).to_be_in_viewport()
    alert_box, button_box = alert.bounding_box(), button.bounding_box()
    assert alert_box is not None
    assert button_box is not None
    assert 0 <= alert_box["y"] - button_box["y"] < 150  # right under the row clicked


def test_a_calibration_minutes_old_is_not_called_an_hour_old(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server)
    row = page.locator("#fleet tbody tr").filter(has_text="checked")
    # Made seconds ago, in this module's set-up: it read "1 h".
    expect(row.locator("td").nth(7)).to_have_text(re.compile(r"^(now|[1-9][0-9]? min)$"))
