"""`tcpcal demo` writes a small realistic fleet through the use cases, with a history that
spans months, and each thing the console flags is in it; it refuses a non-empty database."""

from __future__ import annotations

import sys
from datetime import UTC, datetime
from pathlib import Path

from typer.testing import CliRunner

from app.cli import cli
from tests.conftest import Api, Database


def test_demo_fills_an_empty_database_with_every_case_the_console_shows(
    api: Api, db: Database
) -> None:
    result = CliRunner().invoke(cli, ["demo"])
    assert result.exit_code == 0, result.output
    assert "5 robots, 9 tools, 16 calibrations, 5 checks" in result.output
    # The key it says to make must land in the database it filled, not the default one.
    tcpcal = Path(sys.executable).parent / "tcpcal"  # the path that runs, not a bare name
    assert f"TCPCAL_DATABASE_URL={db.url} {tcpcal} keys create" in result.output

    tools = api.get("/v1/tools", params={"limit": 100}).json()["items"]
    assert len(tools) == 9
    assert len({t["cell"] for t in tools}) == 5
    never = [t["name"] for t in tools if t["active_version"] is None]
    assert never == ["deburr"]
    failed = [
        t["name"] for t in tools if t["last_check"] and not t["last_check"]["within_tolerance"]
    ]
    assert failed == ["torch"]
    out = [t for t in tools if (t["last_calibration"] or {}).get("status") == "out_of_tolerance"]
    assert [t["robot_name"] for t in out] == ["weld14-kr16"]
    now = datetime.now(UTC)
    ages = {
        t["name"] + "@" + t["robot_name"]: (
            now - datetime.fromisoformat(t["last_calibration"]["created_at"])
        ).days
        for t in tools
        if t["last_calibration"]
    }
    assert ages["vacuum@pal2-m20id"] > 500  # a tool nobody calibrated for a year and a half
    assert ages["torch@weld12-kr16"] == 12

    torch = next(t for t in tools if t["name"] == "torch" and t["robot_name"] == "weld12-kr16")
    report = api.get(f"/v1/calibrations/{torch['last_calibration']['id']}").json()
    assert report["quality"]["outliers"] == [2]  # the touch that missed the pin by 3 mm
    assert report["status"] == "accepted"
    assert report["request"]["note"] == "after crash"
    versions = api.get(f"/v1/tools/{torch['id']}/versions").json()
    assert [v["version"] for v in versions["items"]] == [1, 2, 3, 4]
    dates = [v["created_at"] for v in versions["items"]]
    assert dates == sorted(dates)
    assert (now - datetime.fromisoformat(dates[0])).days == 410

    again = CliRunner().invoke(cli, ["demo"])
    assert again.exit_code == 4
    assert "already holds robots" in again.output
    assert len(api.get("/v1/tools", params={"limit": 100}).json()["items"]) == 9


def test_demo_help_claims_no_count_the_fleet_does_not_have() -> None:
    """It said 10 tools for a fleet of 9: the counts are printed by the run, from the fleet."""
    text = CliRunner().invoke(cli, ["demo", "--help"]).output
    assert "10 tools" not in text
    assert "realistic fleet" in text
