"""Fleet rows say why a tool needs attention, judged on the active version as well as the last
calibration and check; they carry the active TCP; `?attention=` filters on the same rules."""

from __future__ import annotations

import csv
import io
import typing
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest

from app.schemas.fleet import AttentionCode
from app.services.fleet.fleet import fleet_of
from app.services.subjects import SERVED
from app.storage.models import clock_at
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses
from tests.conftest import Api


def _out_of_tolerance(api: Api, tool_id: str) -> None:
    bad = simulate_touches(8, seed=2, touch_noise_mm=1.5)
    response = api.post(
        f"/v1/tools/{tool_id}/calibrations",
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(bad)},
        scope="calibrate",
    )
    assert response.json()["status"] == "out_of_tolerance", response.text


def _check(api: Api, tool: dict[str, Any], dx: float) -> None:
    point = api.post(
        f"/v1/robots/{tool['robot_id']}/reference-points",
        {"name": f"pin-{tool['name']}", "position_mm": [500, 0, 300]},
        scope="calibrate",
    ).json()
    body = {
        "reference_point_id": point["id"],
        "format": "xyz_wxyz",
        "poses": [[500 + dx, 0, 400, 0, 1, 0, 0]],
    }
    response = api.post(f"/v1/tools/{tool['id']}/checks", body, scope="calibrate")
    assert response.status_code == 200, response.text


@pytest.fixture
def tools(api: Api) -> dict[str, dict[str, Any]]:
    """The tools of `_tools`: made once per backend, put back for each test (Api.world)."""
    return api.world(_tools)


def _tools(api: Api) -> dict[str, dict[str, Any]]:
    """One tool per attention case, and one that is fine."""
    robot = api.robot("kr16", vendor="KUKA", cell="weld-1")
    made = {
        name: api.tool(robot["id"], name, slot=slot)
        for slot, name in enumerate(
            ["fine", "forced", "last-bad", "check-failed", "uncalibrated"], start=1
        )
    }
    api.manual(made["fine"]["id"], [0, 0, 100])
    # v1 accepted, v2 out of tolerance, v3 accepted; then v2 forced live: the last calibration
    # is fine, the version served is not.
    forced = made["forced"]["id"]
    api.manual(forced, [0, 0, 150])
    _out_of_tolerance(api, forced)
    api.manual(forced, [0, 0, 150.2])
    response = api.post(
        f"/v1/tools/{forced}/versions/2/activate",
        {"force": True, "reason": "interim"},
        scope="calibrate",
    )
    assert response.status_code == 200, response.text
    api.manual(made["last-bad"]["id"], [0, 0, 120])
    _out_of_tolerance(api, made["last-bad"]["id"])
    api.manual(made["check-failed"]["id"], [0, 0, 100])
    _check(api, made["check-failed"], dx=2.0)
    return made


def _rows(api: Api, query: str = "") -> dict[str, dict[str, Any]]:
    response = api.get(f"/v1/tools?limit=500{query}")
    assert response.status_code == 200, response.text
    return {r["name"]: r for r in response.json()["items"]}


def test_every_attention_code_has_its_rule() -> None:
    codes = typing.get_args(AttentionCode)
    assert list(fleet_of(SERVED[0]).rules) == list(codes)  # the tool's: every code


def test_attention_codes_judge_the_active_version_the_last_calibration_and_check(
    api: Api, tools: dict[str, dict[str, Any]]
) -> None:
    rows = _rows(api)
    assert rows["fine"]["attention"] == []
    assert rows["forced"]["attention"] == ["active_out_of_tolerance"]
    assert rows["forced"]["active_version"] == 2
    assert rows["last-bad"]["attention"] == ["last_calibration_out_of_tolerance"]
    assert rows["check-failed"]["attention"] == ["check_failed"]
    assert rows["uncalibrated"]["attention"] == ["no_active_version"]


def test_fleet_rows_carry_the_active_tcp(api: Api, tools: dict[str, dict[str, Any]]) -> None:
    rows = _rows(api)
    assert rows["fine"]["position_mm"] == [0, 0, 100]
    assert rows["fine"]["quaternion"] == [1, 0, 0, 0]
    tcp = api.get(f"/v1/tools/{tools['forced']['id']}/tcp").json()["tcp"]
    assert rows["forced"]["position_mm"] == tcp["position_mm"]
    assert rows["forced"]["quaternion"] == tcp["quaternion"]
    assert rows["uncalibrated"]["position_mm"] is None
    assert rows["uncalibrated"]["quaternion"] is None


def test_attention_filter_uses_the_same_rules(api: Api, tools: dict[str, dict[str, Any]]) -> None:
    flagged = set(_rows(api, "&attention=true"))
    assert flagged == {"forced", "last-bad", "check-failed", "uncalibrated"}
    assert set(_rows(api, "&attention=false")) == {"fine"}
    # with the other filters, and across pages
    assert set(_rows(api, "&attention=true&status=accepted")) == {
        "forced",
        "check-failed",
    }
    seen: list[str] = []
    cursor = ""
    while True:
        page = api.get(f"/v1/tools?attention=true&limit=1{cursor}").json()
        seen += [r["name"] for r in page["items"]]
        if page["next_cursor"] is None:
            break
        cursor = f"&cursor={page['next_cursor']}"
    assert sorted(seen) == sorted(flagged)
    bad = api.get("/v1/tools?attention=maybe")
    assert bad.status_code == 422
    assert bad.json()["errors"][0]["loc"] == ["query", "attention"]


def test_csv_carries_attention_and_the_active_tcp(
    api: Api, tools: dict[str, dict[str, Any]]
) -> None:
    response = api.get("/v1/tools?attention=true", headers={"Accept": "text/csv"})
    table = {r["tool"]: r for r in csv.DictReader(io.StringIO(response.text))}
    assert set(table) == {"forced", "last-bad", "check-failed", "uncalibrated"}
    assert table["forced"]["attention"] == "active_out_of_tolerance"
    assert table["uncalibrated"]["attention"] == "no_active_version"
    assert table["uncalibrated"]["active_z_mm"] == ""
    assert (table["check-failed"]["active_z_mm"], table["check-failed"]["active_qw"]) == (
        "100.000",
        "1.000000000",
    )


def _backdate_calibrations(moment: datetime) -> None:
    from sqlalchemy import update

    from app.storage.db import get_engine
    from app.storage.models import Calibration

    with get_engine().begin() as conn:
        conn.execute(update(Calibration).values(created_at=moment))


def test_stale_after_stale_days_without_calibration_or_check(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    robot = api.robot("old-cell")
    long_ago = datetime.now(UTC) - timedelta(days=200)
    with clock_at(long_ago):
        old = api.tool(robot["id"], "old", slot=1)
        checked = api.tool(robot["id"], "checked-lately", slot=2)
        api.tool(robot["id"], "never", slot=3)
    for tool in (old, checked):
        api.manual(tool["id"], [0, 0, 100])
    _backdate_calibrations(long_ago)
    _check(api, checked, dx=0.1)  # a check today keeps the tool off the stale list
    api.tool(robot["id"], "new", slot=4)
    rows = _rows(api)
    assert rows["old"]["attention"] == ["stale"]
    assert rows["checked-lately"]["attention"] == []
    assert rows["never"]["attention"] == ["no_active_version", "stale"]
    assert rows["new"]["attention"] == ["no_active_version"]

    from app.config import get_settings

    monkeypatch.setenv("TCPCAL_STALE_DAYS", "365")
    get_settings.cache_clear()
    assert _rows(api)["old"]["attention"] == []
