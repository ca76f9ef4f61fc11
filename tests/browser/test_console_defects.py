"""What a new user tripped over in the console, each drawn in a real Chromium (issue 27):
a checks plot of one check (sub-millisecond axis, check_mm line of no length), three empty
panels for a tool without versions, "null" and "nullnull" in a manual calibration's report,
the 412 message drawn far from the button clicked, and "Age 1 h" for a two-minute-old
calibration; and from a later review, controller lines split inside a number ("401." /
"86366") in the "Active TCP for the controllers" cards."""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from urllib.parse import urlsplit

import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, http_client, live_server
from tests.browser.conftest import confirm, sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]


@dataclass
class Cell:
    server: LiveServer
    checked: str  # a tool with one version and one (failed) check
    bare: str  # a tool without versions
    manual: str  # the manual calibration of `checked`
    two: str  # a tool with two versions
    turned: str  # a tool whose TCP is turned and has five decimals: long controller lines
    robot: str  # the robot of them all, without a controller connection


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("defects")
    with (
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
    ):
        with server.client() as http:
            robot = http.post("/v1/robots", json={"name": "r1", "cell": "c1"}).json()
            tools = [
                http.post(f"/v1/robots/{robot['id']}/tools", json={"name": n, "slot": i}).json()
                for i, n in enumerate(("checked", "bare", "two", "turned"), start=1)
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
            turned = {  # turned by 10, -20, 30 deg about x, y, z
                "position_mm": [401.86366, -12.5, 150.25],
                "quaternion": [0.943714364, 0.127679441, -0.144878125, 0.268535823],
            }
            http.post(
                f"/v1/tools/{tools[3]['id']}/calibrations", json={"method": "manual", "tcp": turned}
            ).raise_for_status()
            http.patch(
                f"/v1/tools/{tools[3]['id']}", json={"load": {"mass_kg": 2.0, "cog_mm": [0, 0, 80]}}
            ).raise_for_status()
        yield Cell(
            server,
            tools[0]["id"],
            tools[1]["id"],
            manual["id"],
            tools[2]["id"],
            tools[3]["id"],
            robot["id"],
        )


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


#: Per number of a card's controller line: how many line boxes it is drawn on, and where.
NUMBER_BOXES = """pre => {
    const box = pre.getBoundingClientRect();
    const texts = [];
    const walk = document.createTreeWalker(pre, NodeFilter.SHOW_TEXT);
    while (walk.nextNode()) texts.push(walk.currentNode);
    return texts.flatMap((text) => [...text.data.matchAll(/-?\\d+(?:\\.\\d+)?/g)].map((m) => {
        const range = document.createRange();
        range.setStart(text, m.index);
        range.setEnd(text, m.index + m[0].length);
        const rects = [...range.getClientRects()].filter((r) => r.width > 0);
        return {
            number: m[0],
            lines: new Set(rects.map((r) => Math.round(r.top))).size,
            top: Math.round(rects[0].top),
            inside: rects.every((r) => r.left >= box.left - 0.5 && r.right <= box.right + 0.5),
        };
    }));
}"""


@pytest.mark.parametrize("width", [1400, 900, 500])
def test_controller_lines_wrap_between_numbers_never_inside_one(
    page: Page, cell: Cell, width: int
) -> None:
    page.set_viewport_size({"width": width, "height": 1000})
    sign_in_to(page, cell.server, f"/ui/tools/{cell.turned}")
    cards = page.locator("#controllers .card pre")
    expect(cards).to_have_count(6)
    wrapped = 0
    for pre in cards.all():
        numbers = pre.evaluate(NUMBER_BOXES)
        assert len(numbers) >= 6, numbers  # x, y, z and the orientation at least
        split = [n["number"] for n in numbers if n["lines"] != 1]
        assert split == [], f"split over two lines at {width} px: {split} in {pre.inner_text()!r}"
        hidden = [n["number"] for n in numbers if not n["inside"]]
        assert hidden == [], f"outside the card at {width} px: {hidden}"
        rows = len({n["top"] for n in numbers})
        wrapped += rows > len(pre.inner_text().strip().splitlines())
    # Some line is wider than its card at each width: wrapped, not one long scrolled line.
    assert wrapped, f"no card wraps at {width} px: the test looks at no wrapped line"


def test_a_tool_page_of_a_robot_without_a_controller_logs_only_the_controllers_404(
    page: Page, cell: Cell
) -> None:
    """The page asks GET /v1/robots/{id}/controller and Chromium logs its 404 /no-controller
    (a fixed contract) as a console error. Nothing the console holds says beforehand whether
    the robot has a connection: the robot document has no such field, and a fleet row's
    `controller` is null also for a connection never looked at (reconcile or deploy). So that
    one request stays until the API says so; nothing else on the page may fail."""
    errors: list[str] = []
    failed: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("requestfailed", lambda r: failed.append(f"failed {r.url}"))
    page.on(
        "response",
        lambda r: failed.append(f"{r.status} {urlsplit(r.url).path}") if r.status >= 400 else None,
    )
    sign_in_to(page, cell.server, f"/ui/tools/{cell.turned}")
    expect(page.locator("#controller-none")).to_contain_text("no controller connection")
    expect(page.locator("#controllers .card pre")).to_have_count(6)  # every format, no error
    for _ in range(20):  # Chromium's log message follows the response
        if errors:
            break
        page.wait_for_timeout(100)
    assert failed == [f"404 /v1/robots/{cell.robot}/controller"]
    assert errors == [
        "Failed to load resource: the server responded with a status of 404 (Not Found)"
    ]
