"""The fleet view (JSON and CSV), checks read back, controller text as a file, /docs offline."""

from __future__ import annotations

import csv
import io
import re
from datetime import UTC, datetime

import pytest

from app.jsontypes import JsonObject
from app.storage.models import clock_at
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses
from tests.conftest import Api


@pytest.fixture
def fleet(api: Api) -> dict[str, JsonObject]:
    """The fleet of `_fleet`: built once per backend, put back for each test (Api.world)."""
    return api.world(_fleet)


def _fleet(api: Api) -> dict[str, JsonObject]:
    """3 robots in 2 cells, 9 tools; some calibrated, one out of tolerance."""
    tools: dict[str, JsonObject] = {}
    for r, (robot, cell) in enumerate(
        [("kr16-a", "weld-1"), ("kr16-b", "weld-1"), ("ur10", "pick")]
    ):
        rid = api.robot(robot, cell=cell)["id"]
        for t in range(3):
            name = f"{robot}-t{t}"
            tools[name] = api.tool(rid, name, slot=t + 1)
            if t == 0:
                api.manual(tools[name]["id"], [0, 0, 100 + r])
    bad = simulate_touches(8, seed=2, touch_noise_mm=1.5)
    response = api.post(
        f"/v1/tools/{tools['ur10-t1']['id']}/calibrations",
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(bad)},
        scope="calibrate",
    )
    assert response.json()["status"] == "out_of_tolerance"
    tools["ur10-t1"]["rms_mm"] = response.json()["quality"]["rms_mm"]
    return tools


def test_fleet_lists_every_tool_with_its_robot_and_last_calibration(
    api: Api, fleet: dict[str, JsonObject]
) -> None:
    page = api.get("/v1/tools?limit=500").json()
    rows = {r["name"]: r for r in page["items"]}
    assert len(rows) == 9
    assert rows["kr16-b-t0"]["robot_name"] == "kr16-b"
    assert rows["kr16-b-t0"]["cell"] == "weld-1"
    assert rows["kr16-b-t0"]["active_version"] == 1
    assert rows["kr16-b-t0"]["last_calibration"]["status"] == "accepted"
    assert rows["kr16-a-t2"]["last_calibration"] is None
    assert rows["ur10-t1"]["last_calibration"]["status"] == "out_of_tolerance"
    # the figure read out of the stored result by the database is the calibration's own
    assert rows["ur10-t1"]["last_calibration"]["rms_mm"] == fleet["ur10-t1"]["rms_mm"] > 0.5


@pytest.mark.parametrize(
    ("query", "expected"),
    [
        ("cell=weld-1", {f"kr16-{r}-t{t}" for r in "ab" for t in range(3)}),
        ("cell=pick", {"ur10-t0", "ur10-t1", "ur10-t2"}),
        ("q=KR16-B", {"kr16-b-t0", "kr16-b-t1", "kr16-b-t2"}),
        ("q=ur10-t2", {"ur10-t2"}),
        ("q=%25", set()),  # a literal %, not a wildcard
        ("status=out_of_tolerance", {"ur10-t1"}),
        ("status=accepted&cell=weld-1", {"kr16-a-t0", "kr16-b-t0"}),
    ],
)
def test_fleet_filters(
    api: Api, fleet: dict[str, JsonObject], query: str, expected: set[str]
) -> None:
    names = {r["name"] for r in api.get(f"/v1/tools?{query}").json()["items"]}
    assert names == expected


def test_fleet_by_robot_and_paginated(api: Api, fleet: dict[str, JsonObject]) -> None:
    robot_id = fleet["ur10-t0"]["robot_id"]
    assert len(api.get(f"/v1/tools?robot_id={robot_id}").json()["items"]) == 3
    first = api.get("/v1/tools?limit=4").json()
    second = api.get(f"/v1/tools?limit=4&cursor={first['next_cursor']}").json()
    third = api.get(f"/v1/tools?limit=4&cursor={second['next_cursor']}").json()
    names = [r["name"] for r in first["items"] + second["items"] + third["items"]]
    assert len(names) == len(set(names)) == 9
    assert third["next_cursor"] is None


def test_fleet_csv_has_one_row_per_tool(api: Api, fleet: dict[str, JsonObject]) -> None:
    response = api.get("/v1/tools?limit=2", headers={"Accept": "text/csv"})
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/csv")
    assert "tcpcal-fleet.csv" in response.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(response.text)))
    assert len(rows) == 9  # every tool, not one page
    by_name = {r["tool"]: r for r in rows}
    assert by_name["ur10-t1"]["last_calibration_status"] == "out_of_tolerance"
    assert by_name["kr16-a-t0"]["robot"] == "kr16-a"
    assert re.fullmatch(r"\d+\.\d{3}", by_name["ur10-t1"]["last_calibration_rms_mm"])


def test_checks_are_read_back_newest_first(api: Api, fleet: dict[str, JsonObject]) -> None:
    tool = fleet["kr16-a-t0"]
    robot_id = tool["robot_id"]
    point = api.post(
        f"/v1/robots/{robot_id}/reference-points",
        {"name": "pin", "position_mm": [500, 0, 300]},
        scope="calibrate",
    ).json()
    for dx in (0.1, 2.0):
        body = {
            "reference_point_id": point["id"],
            "format": "xyz_wxyz",
            "poses": [[500 + dx, 0, 400, 0, 1, 0, 0]],
        }
        assert (
            api.post(f"/v1/tools/{tool['id']}/checks", body, scope="calibrate").status_code == 200
        )
    checks = api.get(f"/v1/tools/{tool['id']}/checks").json()["items"]
    assert [c["within_tolerance"] for c in checks] == [False, True]  # newest first
    assert abs(checks[0]["distance_mm"] - 2.0) < 1e-9
    assert checks[0]["summary"].startswith("out of tolerance")
    assert checks[0]["checked_by"] == "test-calibrate"
    page = api.get(f"/v1/tools/{tool['id']}/checks?limit=1").json()
    rest = api.get(f"/v1/tools/{tool['id']}/checks?limit=1&cursor={page['next_cursor']}").json()
    assert [page["items"][0]["id"], rest["items"][0]["id"]] == [c["id"] for c in checks]
    row = {r["name"]: r for r in api.get("/v1/tools").json()["items"]}["kr16-a-t0"]
    assert row["last_check"]["within_tolerance"] is False
    assert api.get("/v1/tools/nope/checks").status_code == 404
    beyond = api.get(f"/v1/tools/{tool['id']}/checks?cursor={'f' * 48}")  # was a 500
    assert beyond.status_code == 200
    assert len(beyond.json()["items"]) == 2


def test_controller_text_as_a_file(api: Api, fleet: dict[str, JsonObject]) -> None:
    tool = fleet["kr16-a-t0"]
    path = f"/v1/tools/{tool['id']}/tcp?format=kuka"
    text = api.get(path, headers={"Accept": "text/plain"})
    assert text.status_code == 200
    assert text.headers["content-type"].startswith("text/plain")
    assert text.headers["content-disposition"] == 'attachment; filename="tool1_kr16-a-t0.dat"'
    as_json = api.get(path).json()
    # The file $config.dat holds (header, TOOL_DATA/TOOL_NAME/LOAD_DATA), no longer the JSON's
    # one line: the same frame, read back by the file's parser.
    assert text.text.endswith("\n")
    assert text.text.startswith("; tcpcal tool data\n")
    assert as_json["controller"]["text"].lstrip("$") in text.text
    assert text.headers["etag"] != api.get(path).headers["etag"]  # two representations
    again = api.get(path, headers={"Accept": "text/plain", "If-None-Match": text.headers["etag"]})
    assert again.status_code == 304
    no_format = api.get(f"/v1/tools/{tool['id']}/tcp", headers={"Accept": "text/plain"})
    assert no_format.status_code == 422
    assert no_format.json()["errors"][0]["loc"] == ["query", "format"]


def test_docs_work_offline(api: Api) -> None:
    page = api.get("/docs")
    assert page.status_code == 200
    assets = re.findall(r'(?:src|href)="([^"]+)"', page.text)
    assert assets
    for url in assets:
        assert url.startswith("/"), f"/docs loads {url} from another host"
        assert api.get(url).status_code == 200, url
    assert "//cdn" not in page.text
    assert api.get("/redoc").status_code == 404


def test_console_is_served_by_the_app_and_names_no_other_host(api: Api) -> None:
    root = api.client.get("/", follow_redirects=False)
    assert root.status_code == 307
    assert root.headers["location"] == "/ui/"
    for path in ("/ui/", "/ui/tools/some-id", "/ui/calibrations/some-id"):
        page = api.get(path)
        assert page.status_code == 200, path
        assert page.headers["content-type"].startswith("text/html")
        csp = page.headers["content-security-policy"]
        assert "default-src 'self'" in csp
        assert "script-src 'self';" in csp  # no inline script, no other host
    shell = api.get("/ui/").text
    assets = re.findall(r'(?:src|href)="([^"]+)"', shell)
    assert "/ui/assets/console.js" in assets
    assert "plotly" not in shell  # loaded by the pages that plot (console.js), not by the shell
    for url in assets:
        assert url.startswith(("/", "data:")), f"the console loads {url} from another host"
    for url in ("/ui/assets/console.js", "/ui/assets/console.css", "/ui/vendor/plotly.min.js"):
        asset = api.get(url)
        assert asset.status_code == 200, url
    script = api.get("/ui/assets/console.js").text
    assert re.findall(r"https?://", script) == []  # the console calls only its own origin
    assert '"/ui/vendor/plotly.min.js"' in script


def test_a_report_gets_the_touches_in_space_and_the_95_percent_ellipsoid(api: Api) -> None:
    import numpy as np

    tool = api.tool(api.robot("kr")["id"])
    touches = simulate_touches(8, seed=5, touch_noise_mm=0.05, outlier_fraction=1 / 8, outlier_mm=3)
    cal = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        json={"method": "xyz_npoint", "format": "kuka_abc", "poses": as_poses(touches, "kuka_abc")},
    ).json()
    detail = api.get(f"/v1/calibrations/{cal['id']}").json()
    geometry = detail["geometry"]
    assert np.allclose(geometry["flange_positions_mm"], touches.f, atol=1e-6)
    tips = np.asarray(geometry["tip_positions_mm"])
    miss = np.linalg.norm(tips - np.asarray(detail["reference_point_mm"]), axis=1)
    # The tips scatter around the point by the residuals the solver reported, the miss too.
    assert np.allclose(miss, detail["quality"]["residuals_mm"], atol=1e-6)
    assert detail["quality"]["outliers"] == [int(np.flatnonzero(touches.outliers)[0])]
    # The ellipsoid: semi-axes^2 are the covariance's eigenvalues times the 95 % factor^2.
    cov = np.asarray(detail["quality"]["tcp_covariance_mm2"])
    k = detail["quality"]["ellipsoid95_scale"]
    semi = np.asarray(geometry["ellipsoid95_semi_axes_mm"])
    assert np.allclose(np.sort(semi**2), np.sort(np.linalg.eigvalsh(cov)) * k**2)
    axes = np.asarray(geometry["ellipsoid95_axes"])
    assert np.allclose(axes @ cov @ axes.T, np.diag(semi**2 / k**2), atol=1e-12)

    manual = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        json={"method": "manual", "tcp": {"position_mm": [0, 0, 150]}},
    ).json()
    assert api.get(f"/v1/calibrations/{manual['id']}").json()["geometry"] is None


def test_fleet_pages_tools_made_at_the_same_instant_each_once_in_id_order(api: Api) -> None:
    """The cursor is (created_at, id): rows sharing a timestamp are told apart by id."""
    rid = api.robot("same-instant")["id"]
    with clock_at(datetime(2026, 1, 1, tzinfo=UTC)):
        made = sorted(api.tool(rid, f"t{i}")["id"] for i in range(7))
    seen: list[str] = []
    cursor = None
    while True:
        page = api.get("/v1/tools?limit=2" + (f"&cursor={cursor}" if cursor else "")).json()
        seen += [row["id"] for row in page["items"]]
        cursor = page["next_cursor"]
        if cursor is None:
            break
    assert seen == made
