"""Frames get fleet rows as tools do (contract v1.4 "Frames": GET /v1/frames with robot name,
cell, active version and frame, last calibration and check, attention, controller, filters
and CSV), through the one fleet (app.services.fleet), and their gauges in /metrics."""

from __future__ import annotations

import csv
import io
from typing import Any

from prometheus_client.parser import text_string_to_metric_families

from tests.api.frame_versions import add_frame_version
from tests.conftest import Api


def _frame(api: Api, robot_id: str, name: str, **fields: Any) -> dict[str, Any]:
    response = api.post(f"/v1/robots/{robot_id}/frames", {"name": name, **fields})
    assert response.status_code == 201, response.text
    return dict(response.json())


def _plant(api: Api) -> dict[str, dict[str, Any]]:
    """Two robots in two cells: a calibrated base, an uncalibrated fixed tool, a base whose
    active version was forced out of tolerance, and a tool (which is not a frame row)."""
    weld = api.robot("kr16-a", vendor="KUKA", cell="weld-1")
    pick = api.robot("kr16-b", vendor="KUKA", cell="pick")
    api.tool(weld["id"], "torch", slot=1)
    frames = {
        "fixture-a": _frame(api, weld["id"], "fixture-a", kind="base", slot=2),
        "nozzle": _frame(api, weld["id"], "nozzle", kind="fixed_tool", slot=5),
        "table": _frame(api, pick["id"], "table", kind="base", slot=1),
    }
    assert add_frame_version(frames["fixture-a"]["id"], [500.0, 10.0, 0.0]) == 1
    activated = api.post(
        f"/v1/frames/{frames['fixture-a']['id']}/versions/1/activate", scope="calibrate"
    )
    assert activated.is_success, activated.text
    table = frames["table"]["id"]
    assert add_frame_version(table, [800.0, 0.0, 0.0], status="out_of_tolerance") == 1
    forced = api.post(
        f"/v1/frames/{table}/versions/1/activate",
        {"force": True, "reason": "table moved, interim"},
        scope="calibrate",
    )
    assert forced.is_success, forced.text
    return frames


def _rows(api: Api, query: str = "") -> dict[str, dict[str, Any]]:
    response = api.get(f"/v1/frames{query}")
    assert response.status_code == 200, response.text
    return {row["name"]: row for row in response.json()["items"]}


def test_each_live_frame_is_a_fleet_row_with_its_robot_value_and_attention(api: Api) -> None:
    frames = _plant(api)
    rows = _rows(api)
    assert list(rows) == ["fixture-a", "nozzle", "table"]  # oldest first; no tool among them
    fixture = rows["fixture-a"]
    assert {k: fixture[k] for k in ("id", "kind", "slot", "robot_name", "cell")} == {
        "id": frames["fixture-a"]["id"],
        "kind": "base",
        "slot": 2,
        "robot_name": "kr16-a",
        "cell": "weld-1",
    }
    assert fixture["active_version"] == 1
    assert fixture["position_mm"] == [500.0, 10.0, 0.0]
    assert fixture["quaternion"] == [1.0, 0.0, 0.0, 0.0]
    assert fixture["attention"] == []
    assert (fixture["last_calibration"], fixture["last_check"]) == (None, None)
    assert fixture["controller"] is None  # never looked at
    assert fixture["live"]["state"] == "unread"  # the frame it moves in: never reconciled
    assert rows["nozzle"]["kind"] == "fixed_tool"
    assert rows["nozzle"]["attention"] == ["no_active_version"]
    assert rows["nozzle"]["position_mm"] is None
    assert rows["table"]["attention"] == ["active_out_of_tolerance"]
    tools = api.get("/v1/tools").json()["items"]
    assert [t["name"] for t in tools] == ["torch"]  # and no frame among the tools


def test_frame_rows_filter_by_cell_robot_name_and_attention(api: Api) -> None:
    frames = _plant(api)
    robot_id = frames["table"]["robot_id"]
    assert list(_rows(api, "?cell=weld-1")) == ["fixture-a", "nozzle"]
    assert list(_rows(api, f"?robot_id={robot_id}")) == ["table"]
    assert list(_rows(api, "?q=NOZ")) == ["nozzle"]
    assert list(_rows(api, "?q=kr16-b")) == ["table"]  # the robot's name too
    assert list(_rows(api, "?attention=true")) == ["nozzle", "table"]
    assert list(_rows(api, "?attention=false")) == ["fixture-a"]
    page = api.get("/v1/frames?limit=2").json()
    assert [r["name"] for r in page["items"]] == ["fixture-a", "nozzle"]
    rest = api.get(f"/v1/frames?limit=2&cursor={page['next_cursor']}").json()
    assert [r["name"] for r in rest["items"]] == ["table"]


def test_frame_fleet_csv_has_one_row_per_frame(api: Api) -> None:
    _plant(api)
    response = api.get("/v1/frames?limit=1", headers={"Accept": "text/csv"})
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/csv")
    assert "tcpcal-frames.csv" in response.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(response.text)))
    assert [r["frame"] for r in rows] == ["fixture-a", "nozzle", "table"]  # all, not a page
    header = response.text.splitlines()[0].split(",")
    assert header[:6] == ["frame_id", "frame", "kind", "slot", "robot", "cell"]
    assert header[-6:] == [
        "drift_rate_mm_per_month",
        "drift_sigma_mm_per_month",
        "drift_crosses_check_at",
        "live_state",
        "live_version",
        "live_checked_at",
    ]  # the frame the robot moves in (app.services.frames.live), after the common columns
    fixture = rows[0]
    assert (fixture["kind"], fixture["slot"], fixture["robot"]) == ("base", "2", "kr16-a")
    assert (fixture["active_version"], fixture["active_x_mm"]) == ("1", "500.000")
    assert rows[1]["attention"] == "no_active_version"
    assert rows[1]["active_x_mm"] == ""


def test_metrics_count_the_frames_as_their_own_family(api: Api) -> None:
    _plant(api)
    samples = {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(api.get("/metrics").text)
        for s in family.samples
    }
    assert samples[("tcpcal_fleet_frames", ())] == 3.0
    assert samples[("tcpcal_fleet_tools", ())] == 1.0
    attention = "tcpcal_fleet_frames_attention"
    assert samples[(attention, (("code", "no_active_version"),))] == 1.0
    assert samples[(attention, (("code", "active_out_of_tolerance"),))] == 1.0
    assert samples[(attention, (("code", "stale"),))] == 0.0
    assert samples[("tcpcal_fleet_frames_controller_state", (("state", "none"),))] == 3.0
