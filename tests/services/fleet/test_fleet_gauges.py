"""The fleet gauges count what the fleet service reports: whatever codes and controller
states its rows declare, each present (0 when no tool has it)."""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC, datetime, timedelta
from typing import Any, Literal

import pytest
from pydantic import BaseModel, Field

from app.schemas.fleet import FleetTool, LastCalibration
from app.services.audit import outbox
from app.services.fleet import gauges as fleet_gauges
from app.services.fleet.gauges import declared_values, read_fleet_gauges
from app.services.subjects import IN_FLEET, SERVED, Served

NOW = datetime(2026, 11, 24, 6, 0, tzinfo=UTC)


class _Controller(BaseModel):
    state: Literal["in_sync", "drifted", "unreachable"]


class _Row(FleetTool):
    # Narrower codes than the fleet's own, on purpose: the gauges count what rows declare.
    attention: list[Literal["check_failed", "stale", "no_active_version"]] = Field(  # type: ignore[assignment]
        default_factory=list
    )
    controller: _Controller | None = None  # type: ignore[assignment]


def _row(n: int, **kw: Any) -> _Row:
    base: dict[str, Any] = {
        "id": f"t{n}",
        "name": f"tool{n}",
        "slot": n,
        "robot_id": "r1",
        "robot_name": "kr16",
        "cell": None,
        "active_version": 1,
        "last_calibration": None,
        "last_check": None,
    }
    return _Row(**{**base, **kw})


def test_declared_values_read_literals_through_lists_and_optionals() -> None:
    assert declared_values(_Row, "attention") == ("check_failed", "stale", "no_active_version")
    assert declared_values(_Controller, "state") == ("in_sync", "drifted", "unreachable")
    assert declared_values(_Row, "name") == ()
    assert declared_values(_Row, "no_such_field") == ()


def test_counts_ages_and_zeros_over_pages(monkeypatch: pytest.MonkeyPatch) -> None:
    cal = LastCalibration(id="c", status="accepted", created_at=NOW - timedelta(days=2),
                          rms_mm=0.1)  # fmt: skip
    rows = [
        _row(1, attention=["check_failed", "stale"], controller=_Controller(state="drifted"),
             last_calibration=cal),
        _row(2, attention=["stale"], controller=_Controller(state="drifted")),
        _row(3),
    ]  # fmt: skip
    pages = {None: (rows[:2], "next"), "next": (rows[2:], None)}  # two pages

    tool = SERVED[0]
    assert tool.fleet is not None
    # The tool's fleet rows of the schema above (the gauges read the codes off its row).
    served = replace(tool, fleet=replace(tool.fleet, row=_Row))

    def fake_list_fleet(session: object, of: Served, **kw: Any) -> tuple[list[_Row], str | None]:
        assert kw["limit"] == fleet_gauges.PAGE
        return pages[kw["cursor"]] if of is served else ([], None)

    monkeypatch.setattr(fleet_gauges, "list_fleet", fake_list_fleet)
    monkeypatch.setattr(fleet_gauges, "IN_FLEET", (served, *IN_FLEET[1:]))
    monkeypatch.setattr(outbox, "oldest_undelivered_age", lambda s: 12.5)
    monkeypatch.setattr(outbox, "undelivered_count", lambda s: 3)
    monkeypatch.setattr(outbox, "publisher_running", lambda e: True)

    class _Session:
        def get_bind(self) -> Any:
            return type("B", (), {"engine": None})()

    fleet = read_fleet_gauges(_Session(), now=NOW)  # type: ignore[arg-type]
    gauges = fleet.subjects[0]
    assert gauges.served is served
    assert gauges.attention == {"check_failed": 1, "stale": 2, "no_active_version": 0}
    assert gauges.controller == {"none": 1, "in_sync": 0, "drifted": 2, "unreachable": 0}
    assert [t.subject_id for t in gauges.items] == ["t1", "t2", "t3"]
    assert gauges.items[0].calibration_age_s == pytest.approx(2 * 86400)
    assert gauges.items[1].calibration_age_s is None
    assert gauges.items[0].attention == ("check_failed", "stale")
    assert (fleet.outbox_oldest_age_s, fleet.outbox_undelivered) == (12.5, 3)
    assert fleet.publisher_running is True
