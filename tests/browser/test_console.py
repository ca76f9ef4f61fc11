"""The console in a real headless Chromium: sign in, the fleet page, a tool, a report.

One live server (SQLite, one worker) holds 3 robots and 9 tools; one torch has an 8-touch
calibration with touch 3 missed by 3 mm, and a tool with two versions is rolled back through
the page. Every page is loaded with requests to any other host aborted and recorded.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import httpx
import numpy as np
import pytest
from playwright.sync_api import Page, expect

from app.kinematics.poses import pose_to_format
from testbed.live_server import LiveServer, fresh_database, http_client, live_server
from testbed.sim.touches import simulate_touches
from tests.browser.conftest import confirm, sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]


@dataclass
class Fleet:
    server: LiveServer
    robots: dict[str, str]  # name -> id
    tools: dict[str, str]  # "robot/tool" -> id
    missed: dict[str, Any]  # the calibration with one missed touch, as JSON


def _touches(seed: int, *, missed: bool = False) -> list[list[float] | list[list[float]]]:
    touches = simulate_touches(
        8,
        seed=seed,
        tcp_mm=np.array([1.0, -0.5, 150.0]),  # one tool: versions differ by noise alone
        touch_noise_mm=0.03,
        outlier_fraction=1 / 8 if missed else 0.0,
        outlier_mm=3,
    )
    if missed:  # put the miss at touch 3 (index 2), where the report must show it
        k = int(touches.outliers.nonzero()[0][0])
        order = [i for i in range(8) if i != k]
        order.insert(2, k)
        return [pose_to_format("kuka_abc", touches.R[i], touches.f[i]) for i in order]
    return [pose_to_format("kuka_abc", r, f) for r, f in zip(touches.R, touches.f, strict=True)]


def _seed(http: httpx.Client) -> tuple[dict[str, str], dict[str, str], dict[str, Any]]:
    robots: dict[str, str] = {}
    tools: dict[str, str] = {}
    layout = {
        "weld12-kr16": ("weld-12", ["torch", "torch-spare", "probe"]),
        "weld14-kr16": ("weld-14", ["torch", "scanner", "probe"]),
        "assy3-irb": ("assy-3", ["gripper", "glue-nozzle", "camera"]),
    }
    for robot, (cell, names) in layout.items():
        robots[robot] = http.post("/v1/robots", json={"name": robot, "cell": cell}).json()["id"]
        for slot, name in enumerate(names, start=1):
            tool = http.post(
                f"/v1/robots/{robots[robot]}/tools",
                json={"name": name, "slot": slot, "load": {"mass_kg": 2.0, "cog_mm": [0, 0, 80]}},
            ).json()
            tools[f"{robot}/{name}"] = tool["id"]
    missed = http.post(
        f"/v1/tools/{tools['weld12-kr16/torch']}/calibrations",
        json={"method": "xyz_npoint", "format": "kuka_abc", "poses": _touches(1, missed=True)},
    ).json()
    for seed, note in ((2, "commissioning"), (3, "after nozzle change")):
        http.post(
            f"/v1/tools/{tools['weld14-kr16/torch']}/calibrations",
            json={
                "method": "xyz_npoint",
                "format": "kuka_abc",
                "poses": _touches(seed),
                "note": note,
            },
        ).raise_for_status()
    return robots, tools, missed


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    tmp = tmp_path_factory.mktemp("console")
    with (
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
    ):
        with server.client() as http:
            robots, tools, missed = _seed(http)
        yield Fleet(server, robots, tools, missed)


@pytest.fixture(scope="module")
def console_server(fleet: Fleet) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return fleet.server


def sign_in(page: Page, fleet: Fleet, path: str = "/") -> None:
    sign_in_to(page, fleet.server, path)


def test_sign_in_is_asked_once_and_the_key_stays_out_of_urls(page: Page, fleet: Fleet) -> None:
    urls: list[str] = []
    page.on("request", lambda request: urls.append(request.url))
    page.goto(fleet.server.url + "/")
    assert page.url == fleet.server.url + "/ui/"  # / redirects to the console
    page.fill("input[name=api_key]", "not-a-key-of-this-server")
    page.click("#sign-in button[type=submit]")
    expect(page.get_by_role("alert")).to_contain_text("not accepted")
    page.fill("input[name=api_key]", fleet.server.admin_key)
    page.click("#sign-in button[type=submit]")
    expect(page.locator("#fleet tbody tr")).to_have_count(9)
    page.click("#fleet a:text-is('gripper')")  # a real navigation: no second sign-in
    expect(page.locator("h1")).to_contain_text("gripper")
    expect(page.locator("input[name=api_key]")).to_have_count(0)
    assert not [u for u in urls if fleet.server.admin_key in u]


def test_fleet_page_finds_tools_flags_attention_and_downloads_csv(page: Page, fleet: Fleet) -> None:
    requested: list[str] = []
    page.on("request", lambda request: requested.append(request.url))
    sign_in(page, fleet)
    rows = page.locator("#fleet tbody tr")
    expect(rows).to_have_count(9)
    # Seven tools were never calibrated: no active TCP is a reason to look.
    expect(page.locator("#fleet tbody tr.attention")).to_have_count(7)
    expect(page.locator("#fleet-summary")).to_have_text("9 tools, 7 need attention")
    torch = rows.filter(has_text="weld12-kr16").filter(has_text="torch").first
    expect(torch).not_to_have_class("attention")
    rms = fleet.missed["quality"]["rms_mm"]
    expect(torch.locator("td").nth(6)).to_have_text(f"{rms:.3f}")

    page.fill("input[name=q]", "weld14")
    expect(rows).to_have_count(3)
    expect(rows.first).to_contain_text("weld14-kr16")
    page.fill("input[name=q]", "")
    page.select_option("select[name=cell]", "assy-3")
    expect(rows).to_have_count(3)
    expect(page.locator("#fleet tbody")).not_to_contain_text("weld")

    with page.expect_download() as info:
        page.click("#csv")
    download = info.value
    assert download.suggested_filename == "tcpcal-fleet.csv"
    text = open(download.path(), encoding="utf-8").read()  # noqa: SIM115 (read at once)
    table = list(csv.DictReader(io.StringIO(text)))
    assert sorted(r["tool"] for r in table) == ["camera", "glue-nozzle", "gripper"]
    # The sign-in and the fleet page draw no plot, and never load Plotly's 3.5 MB.
    assert [url for url in requested if "plotly" in url] == []


def test_report_marks_the_missed_touch_and_shows_the_json_figures(page: Page, fleet: Fleet) -> None:
    cal = fleet.missed
    quality = cal["quality"]
    assert quality["outliers"] == [2], quality  # the solver set touch 3 aside
    sign_in(page, fleet, f"/ui/calibrations/{cal['id']}")
    expect(page.locator("#summary")).to_contain_text(cal["summary"])
    expect(page.locator("[data-field=rms_mm]")).to_have_text(f"{quality['rms_mm']:.3f}")
    expect(page.locator("[data-field=max_mm]")).to_have_text(f"{quality['max_mm']:.3f}")
    expect(page.locator("[data-field=outliers]")).to_have_text("3")
    x, y, z = cal["tcp"]["position_mm"]
    expect(page.locator("[data-field=tcp_mm]")).to_have_text(f"{x:.3f}, {y:.3f}, {z:.3f}")
    with http_client(fleet.server.url) as http:
        detail = http.get(
            f"/v1/calibrations/{cal['id']}",
            headers={"Authorization": f"Bearer {fleet.server.admin_key}"},
        ).json()
    semi = detail["geometry"]["ellipsoid95_semi_axes_mm"]
    expect(page.locator("[data-field=ellipsoid95]")).to_have_text(
        ", ".join(f"{v:.3f}" for v in semi)
    )

    # The residual chart: 8 bars numbered 1..8, the third labelled as the outlier with its value.
    bars = page.locator("#plot-residuals g.point")
    expect(bars).to_have_count(8)
    residual = quality["residuals_mm"][2]
    expect(page.locator("#plot-residuals text.bartext").nth(2)).to_have_text(
        f"{residual:.3f} outlier"
    )
    assert residual > 2.0
    ticks = page.locator("#plot-residuals .xtick text").all_text_contents()
    assert ticks == [str(i) for i in range(1, 9)]
    # The 3-D view is drawn: a WebGL canvas with the flanges, the TCP per touch and the point.
    expect(page.locator("#plot-3d canvas").first).to_be_visible()
    legend = page.locator("#plot-3d .legendtext").all_text_contents()
    assert legend == ["tool (flange to TCP)", "flange", "TCP at each touch", "touched point"]
    expect(page.locator("#warnings")).to_contain_text("set aside")
    expect(page.locator("#raw-request")).to_contain_text('"method": "xyz_npoint"')

    # Printable: the print stylesheet drops the navigation and the buttons, keeps the figures.
    page.emulate_media(media="print")
    expect(page.locator("header.bar")).to_be_hidden()
    expect(page.get_by_role("button", name="Print")).to_be_hidden()
    expect(page.locator("#figures")).to_be_visible()


def test_tool_page_plots_versions_serves_controller_text_and_rolls_back(
    page: Page, fleet: Fleet
) -> None:
    tool_id = fleet.tools["weld14-kr16/torch"]
    auth = {"Authorization": f"Bearer {fleet.server.admin_key}"}
    sign_in(page, fleet, f"/ui/tools/{tool_id}")
    expect(page.locator("#versions tbody tr")).to_have_count(2)
    expect(page.locator("#versions tbody tr.active")).to_contain_text("after nozzle change")
    expect(page.locator("#plot-tcp g.trace.scatter")).to_have_count(3)  # x, y and z over time
    expect(page.locator("#plot-tcp g.errorbar")).to_have_count(6)  # a 1-sigma bar per point
    expect(page.locator("#activations tbody tr")).to_have_count(2)

    kuka = page.locator("#controllers [data-format=kuka]")
    with http_client(fleet.server.url, headers=auth) as http:
        text = http.get(f"/v1/tools/{tool_id}/tcp", params={"format": "kuka"}).json()
    expect(kuka.locator("pre")).to_have_text(text["controller"]["text"])
    expect(page.locator("#controllers .card")).to_have_count(6)
    # Each button says what the file is (issue 27); KUKA's is the $config.dat lines, header
    # first, holding the card's TOOL_DATA without the "$" KUKAVARPROXY reads it by.
    expect(kuka.get_by_role("button", name="Download $config.dat lines")).to_be_visible()
    expect(page.locator("#controllers [data-format=abb] button.download")).to_have_text(
        "Download RAPID module"
    )
    expect(page.locator("#controllers [data-format=fanuc] button.download")).to_have_text(
        "Download TP program (.LS)"
    )
    with page.expect_download() as info:
        kuka.get_by_role("button", name="Download $config.dat lines").click()
    saved = open(info.value.path(), encoding="utf-8").read()  # noqa: SIM115
    assert saved.startswith("; tcpcal tool data\n")
    assert saved.endswith("\n")
    assert text["controller"]["text"].lstrip("$") in saved.splitlines()
    assert info.value.suggested_filename.endswith(".dat")

    # A stale page: someone activates version 1 elsewhere; this page's click gets a 412,
    # explained, and nothing changes.
    with http_client(fleet.server.url, headers=auth) as http:
        http.post(f"/v1/tools/{tool_id}/versions/1/activate").raise_for_status()
        http.post(f"/v1/tools/{tool_id}/versions/2/activate").raise_for_status()
    page.locator("#versions tr[data-version='1'] button").click()
    confirm(page, "back to commissioning")
    expect(page.get_by_role("alert")).to_contain_text("this page is out of date")
    with http_client(fleet.server.url, headers=auth) as http:
        assert http.get(f"/v1/tools/{tool_id}").json()["active_version"] == 2

    # Reloaded, the activation goes through with the fresh ETag.
    page.get_by_role("button", name="Reload").click()
    expect(page.get_by_role("alert")).to_have_count(0)  # the page was drawn again
    page.locator("#versions tr[data-version='1'] button").click()
    confirm(page, "back to commissioning")
    expect(page.locator("#versions tbody tr.active")).to_contain_text("commissioning")
    expect(page.locator("#activations tbody tr").first).to_contain_text("back to commissioning")
    with http_client(fleet.server.url, headers=auth) as http:
        assert http.get(f"/v1/tools/{tool_id}").json()["active_version"] == 1


def test_docs_load_offline(page: Page, fleet: Fleet) -> None:
    page.goto(fleet.server.url + "/docs")
    # Swagger UI draws the title only once it has parsed the whole spec: past Playwright's 5 s
    # on a busy 2-core machine (a fresh clone's make test). What is tested is that it loads
    # with no other host reachable, which the browser fixtures check for every request.
    expect(page.locator(".swagger-ui .title")).to_contain_text("tcpcal", timeout=30_000)
    expect(page.locator(".opblock-summary-path").first).to_be_visible()


def test_a_report_whose_plotly_cannot_load_keeps_its_figures_and_says_so(
    page: Page, fleet: Fleet
) -> None:
    page.route("**/ui/vendor/plotly.min.js", lambda route: route.abort())
    cal = fleet.missed
    sign_in(page, fleet, f"/ui/calibrations/{cal['id']}")
    expect(page.locator("#summary")).to_contain_text(cal["summary"])
    rms = cal["quality"]["rms_mm"]
    expect(page.locator("[data-field=rms_mm]")).to_have_text(f"{rms:.3f}")
    for plot in ("#plot-residuals", "#plot-3d"):
        expect(page.locator(plot)).to_have_text(
            "could not load /ui/vendor/plotly.min.js: the plots are not drawn"
        )
