"""A tool's drift trend, refreshed in the transaction that writes one of its versions, an
activation or a check, and stored on the tool (tools.drift, tools.drift_crosses_at) so that a
fleet page reads one column instead of every tool's history.

Two series (docs/drift.md): the TCP position of each accepted, calibrated version (manual
entries are data-sheet values, not measurements) at its time, projected against the active
version's position; and each check of the active version, its deviation in the flange frame
(t_real - t_active), projected against zero. Each reads the newest MAX_POINTS points through
an index, whatever the length of the history.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import NamedTuple

import numpy as np
from sqlalchemy import ColumnElement, and_, bindparam, select, update
from sqlalchemy.orm import Session

from app.helpers.tolerance import effective_tolerance
from app.jsontypes import JsonArray, JsonObject
from app.methods import ENTERED_BY_HAND
from app.schemas.drift import FleetDrift, SeriesTrend, ToolDrift
from app.services.visible import get_live
from app.solvers.drift import Trend, crossing, fit_trend
from app.storage.db import DriverWrite, HeldRead
from app.storage.models import AuditEvent, TcpVersion, Tool, table_of
from app.words import CHECK_ACTION

#: The newest points of each series that a trend is fitted to.
MAX_POINTS = 60
#: `drifting` when the projection leaves check_mm within this many days of now.
DRIFTING_WITHIN = timedelta(days=30)
_DAY_S = 86400.0
_TOOL = table_of(Tool)


@dataclass(frozen=True, slots=True)
class Point:
    """One point of a series: when, and x y z (mm)."""

    at: datetime
    xyz: Sequence[float]


def crosses_by(until: ColumnElement[datetime]) -> ColumnElement[bool]:
    """The stored projection leaves check_mm by `until`, as a condition on a fleet row: the
    `drifting` attention code with `until` bound to now + DRIFTING_WITHIN."""
    return and_(Tool.drift_crosses_at.is_not(None), Tool.drift_crosses_at <= until)


def fleet_drift(stored: JsonObject | None) -> FleetDrift | None:
    """The fleet row's drift from the stored trend."""
    if not stored or stored.get("fleet") is None:
        return None
    return ToolDrift.model_validate(stored).fleet


class StoredDrift(NamedTuple):
    """A fitted trend as the tool's columns store it."""

    drift: JsonObject
    drift_crosses_at: datetime | None


def stored(drift: ToolDrift) -> StoredDrift:
    """The values of the tool's columns that store `drift`."""
    return StoredDrift(
        drift.model_dump(mode="json"), drift.fleet.crosses_check_at if drift.fleet else None
    )


def fit_drift(
    session: Session,
    *,
    tool_id: str,
    active_version: int | None,
    tolerance: JsonObject | None,
    pending_check: Point | None = None,
) -> ToolDrift:
    """Both trends of a tool against its tolerance's check_mm (`compute_drift`)."""
    return compute_drift(
        session,
        tool_id=tool_id,
        active_version=active_version,
        check_mm=effective_tolerance(tolerance).check_mm,
        pending_check=pending_check,
    )


def refresh_drift(
    session: Session,
    *,
    tool_id: str,
    active_version: int | None,
    tolerance: JsonObject | None,
    pending_check: Point | None = None,
) -> ToolDrift:
    """Fit the tool's trends and store them on the tool, in the caller's transaction.
    `pending_check`: a check recorded in this transaction (the audit trail is written at
    commit, so the query cannot see it yet)."""
    drift = fit_drift(
        session,
        tool_id=tool_id,
        active_version=active_version,
        tolerance=tolerance,
        pending_check=pending_check,
    )
    _SAVE_DRIFT.execute(session, [{"tool_id": tool_id, **stored(drift)._asdict()}])
    cached = session.identity_map.get(session.identity_key(Tool, tool_id))
    if cached is not None:
        session.expire(cached, ["drift", "drift_crosses_at"])
    return drift


def restate_drift(session: Session, tool: Tool) -> None:
    """Refit a tool (an ORM object being changed) after its tolerance changed."""
    tool.drift, tool.drift_crosses_at = stored(
        fit_drift(
            session, tool_id=tool.id, active_version=tool.active_version, tolerance=tool.tolerance
        )
    )


def tool_drift(session: Session, tool_id: str) -> ToolDrift:
    """A live tool's drift trends (404 otherwise)."""
    return stored_or_computed(session, get_live(session, Tool, tool_id, for_update=False))


def stored_or_computed(session: Session, tool: Tool) -> ToolDrift:
    """The tool's stored trend; computed (not stored) for a tool written before trends were."""
    if tool.drift is not None:
        return ToolDrift.model_validate(tool.drift)
    return fit_drift(
        session, tool_id=tool.id, active_version=tool.active_version, tolerance=tool.tolerance
    )


def compute_drift(
    session: Session,
    *,
    tool_id: str,
    active_version: int | None,
    check_mm: float,
    pending_check: Point | None = None,
) -> ToolDrift:
    """Both trends of a tool and the one a fleet row shows."""
    session.flush()  # the reads below go to the driver: pending ORM changes first
    positions = _version_points(session, tool_id)
    active_mm = _active_position(session, tool_id, active_version)
    checks = _check_points(session, tool_id, active_version)
    if pending_check is not None:
        checks.append(pending_check)
    versions_trend = _series(positions, active_mm, check_mm)
    checks_trend = _series(checks, [0.0, 0.0, 0.0], check_mm)
    fleet = None
    for basis, trend in (("checks", checks_trend), ("versions", versions_trend)):
        if trend is not None:
            fleet = FleetDrift(
                basis=basis,
                rate_mm_per_month=trend.speed_mm_per_month,
                sigma_mm_per_month=trend.speed_sigma_mm_per_month,
                crosses_check_at=trend.crosses_check_at,
            )
            break
    return ToolDrift(
        tool_id=tool_id,
        active_version=active_version,
        check_mm=check_mm,
        versions=versions_trend,
        checks=checks_trend,
        fleet=fleet,
    )


def _series(
    points: Sequence[Point], reference_mm: Sequence[float] | None, check_mm: float
) -> SeriesTrend | None:
    if not points:
        return None
    days = np.array([p.at.timestamp() / _DAY_S for p in points])
    trend = fit_trend(days, np.array([list(p.xyz) for p in points], dtype=np.float64))
    if trend is None:
        return None
    crosses = None
    if reference_mm is not None:
        at = crossing(trend, reference_mm=reference_mm, limit_mm=check_mm)
        crosses = None if at is None else _moment(at)
    return _document(trend, crosses)


def _document(trend: Trend, crosses: datetime | None) -> SeriesTrend:
    return SeriesTrend(
        n=trend.n,
        first_at=_moment(trend.first_days),
        last_at=_moment(trend.last_days),
        t0_at=_moment(trend.t0_days),
        level_mm=trend.level_mm.tolist(),
        rate_mm_per_month=trend.rate_mm_per_month.tolist(),
        sigma_mm_per_month=trend.sigma_mm_per_month.tolist(),
        low_mm_per_month=trend.low_mm_per_month.tolist(),
        high_mm_per_month=trend.high_mm_per_month.tolist(),
        speed_mm_per_month=trend.speed_mm_per_month,
        speed_sigma_mm_per_month=trend.speed_sigma_mm_per_month,
        outliers=len(trend.outliers),
        crosses_check_at=crosses,
    )


def _moment(days: float) -> datetime:
    return datetime.fromtimestamp(days * _DAY_S, UTC)


# The series are read on the driver's cursor in the caller's transaction (app.storage.db.HeldRead):
# through Session.execute the three reads and the UPDATE of a refit cost a stored calibration
# more than its solve (bench/write_path.py).
class _VersionPoint(NamedTuple):
    created_at: datetime
    position_mm: JsonArray


class _ActivePosition(NamedTuple):
    position_mm: JsonArray


class _CheckPoint(NamedTuple):
    at: datetime
    details: JsonObject | None


_VERSION_POINTS = HeldRead(
    _VersionPoint,
    select(TcpVersion.created_at, TcpVersion.position_mm)
    .where(
        TcpVersion.tool_id == bindparam("tool_id"),
        TcpVersion.status == "accepted",
        # NOT IN of the methods entered by hand, one condition each (source is never NULL):
        # a held read's statement is compiled once, with no list to expand
        *(TcpVersion.source != method for method in ENTERED_BY_HAND),
    )
    .order_by(TcpVersion.version.desc())
    .limit(MAX_POINTS),
)
_ACTIVE_POSITION = HeldRead(
    _ActivePosition,
    select(TcpVersion.position_mm).where(
        TcpVersion.tool_id == bindparam("tool_id"), TcpVersion.version == bindparam("version")
    ),
)
_CHECK_POINTS = HeldRead(
    _CheckPoint,
    select(AuditEvent.at, AuditEvent.details)
    .where(AuditEvent.tool_id == bindparam("tool_id"), AuditEvent.action == CHECK_ACTION)
    .order_by(AuditEvent.id.desc())
    .limit(MAX_POINTS),
)
_SAVE_DRIFT = DriverWrite(
    update(_TOOL)
    .where(_TOOL.c.id == bindparam("tool_id"))
    .values(drift=bindparam("drift"), drift_crosses_at=bindparam("drift_crosses_at"))
)


def _version_points(session: Session, tool_id: str) -> list[Point]:
    """The newest accepted, measured versions (seek in the (tool_id, version) index)."""
    return [
        Point(at, [float(v) for v in xyz])
        for at, xyz in _VERSION_POINTS.all_in(session, tool_id=tool_id)
    ]


def _active_position(
    session: Session, tool_id: str, active_version: int | None
) -> list[float] | None:
    if active_version is None:
        return None
    row = _ACTIVE_POSITION.one_or_none_in(session, tool_id=tool_id, version=active_version)
    return None if row is None else [float(v) for v in row.position_mm]


def _check_points(session: Session, tool_id: str, active_version: int | None) -> list[Point]:
    """The newest checks of the active version (seek in the (tool_id, action, id) index):
    each one's deviation in the flange frame, t_real - t_active (base frame for checks
    recorded before the flange deviation was)."""
    if active_version is None:
        return []
    points = []
    for at, details in _CHECK_POINTS.all_in(session, tool_id=tool_id):
        d = details or {}
        xyz = d.get("deviation_flange_mm") or d.get("deviation_mm")
        if d.get("version") == active_version and isinstance(xyz, list) and len(xyz) == 3:
            points.append(Point(at, [float(v) for v in xyz]))
    return points
