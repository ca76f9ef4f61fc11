"""The fleet view (JSON and CSV), checks read back, controller text as a file, /docs offline."""

from __future__ import annotations

import csv
import io
import re

import pytest

from app.jsontypes import JsonObject
from tests.api.touches import as_poses
from tests.conftest import Api
from tests.sim.touches import simulate_touches


@pytest.fixture
def fleet(api: Api) -> dict[str, JsonObject]:
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
    assert rows["ur10-t1"]["last_calibration"]["rms_mm"] > 0.5


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
    assert text.text == as_json["controller"]["text"]
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
