"""/metrics carries the fleet's state: tools by attention code and controller state, and
each tool's seconds since its last calibration and check, read from the database."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest
from prometheus_client.parser import text_string_to_metric_families
from sqlalchemy import update

from app.schemas.fleet import FleetTool
from app.storage.db import session_scope
from app.storage.models import Calibration, Tool, clock_at
from tests.conftest import Api

DAY = 86400.0


def _samples(text: str) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    return {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(text)
        for s in family.samples
    }


def _check(api: Api, robot_id: str, tool_id: str, offset_mm: float) -> None:
    point = api.post(
        f"/v1/robots/{robot_id}/reference-points",
        {"name": f"pin-{tool_id[:8]}", "position_mm": [500, 0, 300]},
        scope="calibrate",
    )
    assert point.status_code == 201, point.text
    check = api.post(
        f"/v1/tools/{tool_id}/checks",
        {
            "reference_point_id": point.json()["id"],
            "format": "xyz_wxyz",
            "poses": [[500 + offset_mm, 0, 400, 0, 1, 0, 0]],
        },
        scope="calibrate",
    )
    assert check.status_code == 200, check.text


def _backdate_calibrations(tool_id: str, at: datetime) -> None:
    # calibrations are stored by a solver process, whose clock clock_at does not reach;
    # the tool is made as old (a tool registered lately is not stale, whatever its history)
    with session_scope(write=True) as session:
        session.execute(
            update(Calibration).where(Calibration.tool_id == tool_id).values(created_at=at)
        )
        session.execute(update(Tool).where(Tool.id == tool_id).values(created_at=at))


def test_metrics_show_each_tools_ages_and_fleet_counts(api: Api) -> None:
    now = datetime.now(UTC)
    robot = api.robot("cell12-kr16")
    torch = api.tool(robot["id"], "torch", slot=1)
    gripper = api.tool(robot["id"], "gripper", slot=2)
    spare = api.tool(robot["id"], "spare", slot=3)  # never calibrated: no age series
    gone = api.tool(robot["id"], "gone", slot=4)
    api.manual(torch["id"], [0, 0, 150])
    _backdate_calibrations(torch["id"], now - timedelta(days=200))
    api.manual(gripper["id"], [0, 0, 100])
    _backdate_calibrations(gripper["id"], now - timedelta(days=10))
    with clock_at(now - timedelta(days=10)):
        _check(api, robot["id"], gripper["id"], 0.1)
    api.manual(gone["id"], [0, 0, 90])
    assert api.delete(f"/v1/tools/{gone['id']}").status_code in (200, 204)

    response = api.get("/metrics")
    assert response.status_code == 200, response.text
    samples = _samples(response.text)
    after = (datetime.now(UTC) - now).total_seconds()

    def tool(name: str, t: dict[str, str]) -> tuple[str, tuple[tuple[str, str], ...]]:
        labels = {"tool_id": t["id"], "robot": "cell12-kr16", "tool": t["name"]}
        return name, tuple(sorted(labels.items()))

    calibration = "tcpcal_tool_last_calibration_age_seconds"
    check = "tcpcal_tool_last_check_age_seconds"
    assert samples[tool(calibration, torch)] == pytest.approx(200 * DAY, abs=after + 1)
    assert samples[tool(calibration, gripper)] == pytest.approx(10 * DAY, abs=after + 1)
    assert samples[tool(check, gripper)] == pytest.approx(10 * DAY, abs=after + 1)
    assert tool(check, torch) not in samples  # never checked
    assert tool(calibration, spare) not in samples  # never calibrated
    assert not any(gone["id"] in str(key) for key in samples)  # archived: out of the fleet
    assert samples[("tcpcal_fleet_tools", ())] == 3
    assert samples[("tcpcal_fleet_gauges_up", ())] == 1
    # no robot has a controller connection: every live tool counts as "none"
    assert samples[("tcpcal_fleet_tools_controller_state", (("state", "none"),))] == 3
    if "attention" in FleetTool.model_fields:  # the fleet service judges attention codes
        flagged = "tcpcal_tool_attention"
        spare_labels = dict(tool(flagged, spare)[1], code="no_active_version")
        torch_labels = dict(tool(flagged, torch)[1], code="stale")  # 200 days > 180
        assert samples[(flagged, tuple(sorted(spare_labels.items())))] == 1
        assert samples[(flagged, tuple(sorted(torch_labels.items())))] == 1
        by_code = "tcpcal_fleet_tools_attention"
        assert samples[(by_code, (("code", "no_active_version"),))] >= 1
        assert samples[(by_code, (("code", "check_failed"),))] == 0
    # the request counters are still there beside the fleet's state
    assert any(name == "tcpcal_http_requests_total" for name, _ in samples)


def test_metrics_of_an_empty_fleet_are_zero_not_missing(api: Api) -> None:
    samples = _samples(api.get("/metrics").text)
    assert samples[("tcpcal_fleet_tools", ())] == 0
    assert samples[("tcpcal_fleet_tools_controller_state", (("state", "none"),))] == 0
    assert not any(name == "tcpcal_tool_last_calibration_age_seconds" for name, _ in samples)
