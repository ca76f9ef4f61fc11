"""A subject's drift trend, refreshed in the transaction that writes one of its versions, an
activation or a check, and stored on the subject's row (`drift`, `drift_crosses_at`) so that
a fleet page reads one column instead of every subject's history.

Two series (docs/drift.md): the position of each accepted, calibrated version (manual entries
are data-sheet values, not measurements) at its time, projected against the active version's
position; and each check of the active version, its deviation (in the flange frame for a
tool), projected against zero. Each reads the newest MAX_POINTS points through an index,
whatever the length of the history. The stored document names the subject by its key
(`{"tool_id": ...}`), as the subject's drift schema does (app.schemas.drift.ToolDrift).
"""

from __future__ import annotations

import functools
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
from app.schemas.drift import FleetDrift, SeriesTrend
from app.services.lifecycle.subject import AnySubject, Locked, SubjectRow
from app.solvers.drift import Trend, crossing, fit_trend
from app.storage.db import DriverWrite, HeldRead
from app.storage.models import AuditEvent, table_of

#: What a fit reads (id, active_version, tolerance) of: a subject's row, or one under its lock.
Fitted = Locked | SubjectRow
#: The newest points of each series that a trend is fitted to.
MAX_POINTS = 60
#: `drifting` when the projection leaves check_mm within this many days of now.
DRIFTING_WITHIN = timedelta(days=30)
_DAY_S = 86400.0


@dataclass(frozen=True, slots=True)
class Point:
    """One point of a series: when, and x y z (mm)."""

    at: datetime
    xyz: Sequence[float]


def crosses_by(subject: AnySubject, until: ColumnElement[datetime]) -> ColumnElement[bool]:
    """The stored projection leaves check_mm by `until`, as a condition on a fleet row: the
    `drifting` attention code with `until` bound to now + DRIFTING_WITHIN."""
    crosses_at = subject.table.c.drift_crosses_at
    return and_(crosses_at.is_not(None), crosses_at <= until)


def fleet_drift(stored: JsonObject | None) -> FleetDrift | None:
    """The fleet row's drift from the stored trend."""
    fleet = None if not stored else stored.get("fleet")
    return None if fleet is None else FleetDrift.model_validate(fleet)


class StoredDrift(NamedTuple):
    """A fitted trend as the subject's columns store it: the document, and when its
    projection leaves check_mm (None when it does not)."""

    drift: JsonObject
    drift_crosses_at: datetime | None


def fit_drift(
    session: Session, subject: AnySubject, row: Fitted, pending_check: Point | None = None
) -> StoredDrift:
    """Both trends of a subject against its tolerance's check_mm (`compute_drift`).
    `pending_check`: a check recorded in this transaction (the audit trail is written at
    commit, so the query cannot see it yet)."""
    return compute_drift(
        session,
        subject,
        subject_id=row.id,
        active_version=row.active_version,
        check_mm=effective_tolerance(row.tolerance).check_mm,
        pending_check=pending_check,
    )


def store_drift(
    session: Session, subject: AnySubject, subject_id: str, fitted: StoredDrift
) -> None:
    """Store fitted trends on the subject's row, in the caller's transaction."""
    _reads(subject).save.execute(session, [{"subject_id": subject_id, **fitted._asdict()}])
    cached = session.identity_map.get(session.identity_key(subject.model, subject_id))
    if cached is not None:
        session.expire(cached, ["drift", "drift_crosses_at"])


def compute_drift(
    session: Session,
    subject: AnySubject,
    *,
    subject_id: str,
    active_version: int | None,
    check_mm: float,
    pending_check: Point | None = None,
) -> StoredDrift:
    """Both trends of a subject and the one a fleet row shows."""
    session.flush()  # the reads below go to the driver: pending ORM changes first
    reads = _reads(subject)
    positions = _version_points(session, reads, subject_id)
    active_mm = _active_position(session, reads, subject_id, active_version)
    checks = _check_points(session, subject, reads, subject_id, active_version)
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
    document: JsonObject = {
        subject.key: subject_id,
        "active_version": active_version,
        "check_mm": check_mm,
        "versions": _dumped(versions_trend),
        "checks": _dumped(checks_trend),
        "fleet": _dumped(fleet),
    }
    return StoredDrift(document, fleet.crosses_check_at if fleet else None)


def _dumped(model: SeriesTrend | FleetDrift | None) -> JsonObject | None:
    return None if model is None else model.model_dump(mode="json")


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


class _Reads(NamedTuple):
    versions: HeldRead[_VersionPoint]
    active: HeldRead[_ActivePosition]
    checks: HeldRead[_CheckPoint]
    save: DriverWrite


@functools.cache
def _reads(subject: AnySubject) -> _Reads:
    """A subject's series reads and its trend's write, built once."""
    versions, key = subject.versions, subject.version_key()
    audit = table_of(AuditEvent)
    by_subject = key == bindparam("subject_id")
    return _Reads(
        HeldRead(
            _VersionPoint,
            select(versions.c.created_at, versions.c.position_mm)
            .where(
                by_subject,
                versions.c.status == "accepted",
                # NOT IN of the methods entered by hand, one condition each (source is never
                # NULL): a held read's statement is compiled once, with no list to expand
                *(versions.c.source != method for method in ENTERED_BY_HAND),
            )
            .order_by(versions.c.version.desc())
            .limit(MAX_POINTS),
        ),
        HeldRead(
            _ActivePosition,
            select(versions.c.position_mm).where(
                by_subject, versions.c.version == bindparam("version")
            ),
        ),
        HeldRead(
            _CheckPoint,
            select(audit.c.at, audit.c.details)
            .where(
                subject.audit_key() == bindparam("subject_id"),
                audit.c.action == subject.check_action,
            )
            .order_by(audit.c.id.desc())
            .limit(MAX_POINTS),
        ),
        DriverWrite(
            update(subject.table)
            .where(subject.table.c.id == bindparam("subject_id"))
            .values(drift=bindparam("drift"), drift_crosses_at=bindparam("drift_crosses_at"))
        ),
    )


def _version_points(session: Session, reads: _Reads, subject_id: str) -> list[Point]:
    """The newest accepted, measured versions (seek in the (key, version) index)."""
    return [
        Point(at, [float(v) for v in xyz])
        for at, xyz in reads.versions.all_in(session, subject_id=subject_id)
    ]


def _active_position(
    session: Session, reads: _Reads, subject_id: str, active_version: int | None
) -> list[float] | None:
    if active_version is None:
        return None
    row = reads.active.one_or_none_in(session, subject_id=subject_id, version=active_version)
    return None if row is None else [float(v) for v in row.position_mm]


def _check_points(
    session: Session,
    subject: AnySubject,
    reads: _Reads,
    subject_id: str,
    active_version: int | None,
) -> list[Point]:
    """The newest checks of the active version (seek in the (key, action, id) index): each
    one's deviation, t_real - t_active, in the flange frame (the base frame for checks
    recorded before the flange deviation was)."""
    if active_version is None or subject.check_action is None:
        return []
    points = []
    for at, details in reads.checks.all_in(session, subject_id=subject_id):
        d = details or {}
        xyz = d.get("deviation_flange_mm") or d.get("deviation_mm")
        if d.get("version") == active_version and isinstance(xyz, list) and len(xyz) == 3:
            points.append(Point(at, [float(v) for v in xyz]))
    return points
