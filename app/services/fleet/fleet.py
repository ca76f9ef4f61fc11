"""The fleet: every live subject of every robot (each of app.services.subjects: tools,
frames) with its active version, last calibration, last check and why it needs attention,
and a subject's checks read back (a check is recorded once, in the audit trail).

Written once for every subject: the statements are built from its `Subject` (its tables,
its key, its check action, its controller states) and its `FleetSide` (its row schema, its
own columns, the parts it adds: app.services.lifecycle.fleet), once per subject.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from functools import cache
from typing import Any, Protocol, cast, get_args

from sqlalchemy import (
    BindParameter,
    ColumnElement,
    FromClause,
    Row,
    ScalarSelect,
    Select,
    Table,
    and_,
    bindparam,
    false,
    func,
    or_,
    select,
)
from sqlalchemy.orm import Session

from app.config import get_settings
from app.helpers.pagination import paginate_newest_first, paginate_rows
from app.jsontypes import JsonObject
from app.schemas.drift import FleetDrift
from app.schemas.fleet import (
    AnyAttentionCode,
    AttentionCode,
    CheckRecord,
    FleetController,
    FrameAttentionCode,
    LastCalibration,
    LastCheck,
)
from app.services.lifecycle.activation import CHECK_CORRECTION
from app.services.lifecycle.drift import DRIFTING_WITHIN, crosses_by, fleet_drift
from app.services.lifecycle.fleet import Column, FleetSide
from app.services.lifecycle.subject import AnySubject
from app.services.lifecycle.versions import get_live
from app.services.subjects import Served
from app.services.visible import in_scope
from app.storage.models import AuditEvent, Robot, table_of, utcnow

OUT_OF_TOLERANCE = "out_of_tolerance"
#: A subject corrected by re-checks more than TCPCAL_CORRECTIONS_ALERT times in this long
#: keeps getting hit (`frequent_corrections`).
CORRECTIONS_WITHIN = timedelta(days=30)
#: The verdicts of a check that corrected the active version (app.services.checks.recheck).
CORRECTED = ("corrected", "deployment_failed")
#: Every attention code in the order rows list them: a tool's (app.schemas.fleet.AttentionCode),
#: then a frame's own (FrameAttentionCode lists them in the same order).
CODES: tuple[AnyAttentionCode, ...] = tuple(
    dict.fromkeys((*get_args(AttentionCode), *get_args(FrameAttentionCode)))
)

_AUDIT = table_of(AuditEvent)
#: The page's subjects by id (an expanding parameter: the statements are built once).
_IDS: BindParameter[list[str]] = bindparam("ids", expanding=True)


def rule_moments(now: datetime) -> dict[str, datetime | int]:
    """The moments (and limits) the rules compare with at `now`: the parameters of the
    rules (`Fleet.rules`)."""
    settings = get_settings()
    return {
        "stale_before": now - timedelta(days=settings.stale_days),
        "drifting_until": now + DRIFTING_WITHIN,
        "corrections_since": now - CORRECTIONS_WITHIN,
        "corrections_alert": settings.corrections_alert,
    }


class FleetRow(Protocol):
    """What the fleet's readers (its CSV, the gauges, the plant) read of a fleet row, any
    subject's (its schema is the subject's: app.services.lifecycle.fleet.FleetSide.row)."""

    # who it is
    id: str
    name: str
    robot_id: str
    robot_name: str
    cell: str | None
    # what is judged of it
    attention: Sequence[str]
    controller: FleetController | None
    drift: FleetDrift | None
    last_calibration: LastCalibration | None
    last_check: LastCheck | None
    # its active version
    active_version: int | None
    position_mm: list[float] | None
    quaternion: list[float] | None


@dataclass(frozen=True, eq=False)
class Fleet:
    """A subject's fleet statements, built once (`fleet_of`): `rules`, each attention code's
    condition on a fleet row (the subject's table, its robot and its active version joined:
    the codes a row shows and `?attention=` are both these, each an index seek per subject,
    never a scan of calibrations, versions or checks), in the order rows list them;
    `columns`, what a row shows of its subject, robot and active version."""

    served: Served
    side: FleetSide
    active: FromClause
    states: Table | None
    rules: dict[AnyAttentionCode, ColumnElement[bool]]
    columns: tuple[Column, ...]
    attention: Statement
    calibrations: Statement
    checks: Statement | None

    @property
    def subject(self) -> AnySubject:
        return self.served.subject


#: A statement of any columns.
Statement = Select[*tuple[Any, ...]]
#: Attention codes' rules, each a condition on a fleet row.
_Rules = dict[AnyAttentionCode, ColumnElement[bool]]


def _newest_calibration(subject: AnySubject, column: str) -> ScalarSelect[object]:
    """`column` of the subject's newest calibration, correlated to its table: a seek in the
    (<key>, created_at, id) index whatever the length of its history."""
    cal, table = subject.calibrations, subject.table
    return (
        select(cal.c[column])
        .where(cal.c[subject.key] == table.c.id)
        .order_by(cal.c.created_at.desc(), cal.c.id.desc())
        .limit(1)
        .correlate(table)
        .scalar_subquery()
    )


def _newest_check(subject: AnySubject, column: Column) -> ScalarSelect[object]:
    """`column` of the subject's newest check, correlated to its table: a seek in the
    (<key>, action, id) index of the audit trail."""
    return (
        select(column)
        .where(subject.audit_key() == subject.table.c.id, _AUDIT.c.action == subject.check_action)
        .order_by(_AUDIT.c.id.desc())
        .limit(1)
        .correlate(subject.table)
        .scalar_subquery()
    )


def _check_rules(subject: AnySubject, cutoff: ColumnElement[datetime]) -> _Rules:
    """The rules that read the subject's checks (none for a subject that has no checks), and
    `stale`: nothing done to it for stale_days, neither calibrated nor checked (a subject
    registered less long ago is not stale yet)."""
    created = subject.table.c.created_at
    calibrated = func.coalesce(_newest_calibration(subject, "created_at"), created) < cutoff
    if subject.check_action is None:
        return {"stale": calibrated}
    details = _AUDIT.c.details
    return {
        # The newest check found it out of tolerance and did not correct it (a re-check
        # that did is a new active version, judged by the other rules).
        "check_failed": and_(
            _newest_check(subject, details["within_tolerance"].as_boolean()) == false(),
            func.coalesce(_newest_check(subject, details["verdict"].as_string()), "").not_in(
                CORRECTED
            ),
        ),
        "stale": and_(
            calibrated, func.coalesce(_newest_check(subject, _AUDIT.c.at), created) < cutoff
        ),
    }


def _state_rules(subject: AnySubject, states: Table | None) -> _Rules:
    """What the last reconcile or deployment found in the robot's controller (none for a
    subject not deployed)."""
    if states is None:
        return {}
    table = subject.table
    state = (
        select(states.c.state)
        .where(states.c[subject.key] == table.c.id)
        .correlate(table)
        .scalar_subquery()
    )
    return {
        "controller_drifted": state == "drifted",
        "controller_unreachable": state == "unreachable",
    }


def _rules(served: Served, side: FleetSide, active: FromClause, states: Table | None) -> _Rules:
    """Every rule of a subject's rows, their moments bound parameters (`rule_moments`):
    building the rules' subqueries cost a page 2 ms of Python, so they are built once."""
    subject = served.subject
    table, activations = subject.table, subject.activations
    corrections = (
        select(func.count(activations.c.id))
        .where(
            subject.activation_key() == table.c.id,
            activations.c.reason == CHECK_CORRECTION,
            activations.c.activated_at >= bindparam("corrections_since"),
        )
        .correlate(table)
        .scalar_subquery()
    )
    rules: _Rules = {
        "active_out_of_tolerance": active.c.status == OUT_OF_TOLERANCE,
        "last_calibration_out_of_tolerance": (
            _newest_calibration(subject, "status") == OUT_OF_TOLERANCE
        ),
        "no_active_version": table.c.active_version.is_(None),
        **_check_rules(subject, bindparam("stale_before")),
        **_state_rules(subject, states),
        # The trend stored when a version or check was written projects out of check_mm.
        "drifting": crosses_by(subject, bindparam("drifting_until")),
        # Corrected by re-checks more often than TCPCAL_CORRECTIONS_ALERT in 30 days.
        "frequent_corrections": corrections > bindparam("corrections_alert"),
    }
    for part in side.parts:
        rules.update(part.rules)
    return {code: rules[code] for code in CODES if code in rules}


@cache
def fleet_of(served: Served) -> Fleet:
    """A subject's fleet statements (built on first use, then kept)."""
    subject, side = served.subject, served.fleet
    if side is None:
        raise ValueError(f"{subject.kind} declares no fleet rows (app.services.subjects)")
    table = subject.table
    active = subject.versions.alias("active")
    states = subject.states
    rules = _rules(served, side, active, states)
    key = subject.key
    on_active = and_(active.c[key] == table.c.id, active.c.version == table.c.active_version)
    columns = (
        table.c.id,
        table.c.name,
        *(table.c[name] for name in side.columns),
        table.c.robot_id,
        table.c.active_version,
        table.c.created_at,
        Robot.name.label("robot_name"),
        Robot.cell,
        active.c.position_mm,
        active.c.quaternion,
        table.c.drift,
    )
    state_columns: tuple[Column, ...] = ()
    attention = select(table.c.id)
    if states is not None:
        state = states.alias("controller_state")
        state_columns = tuple(state.c[name] for name in _STATE_COLUMNS)
    attention = (
        select(
            table.c.id,
            *state_columns,
            *(column for part in side.parts for column in part.columns),
            *(rule.label(f"rule_{i}") for i, rule in enumerate(rules.values())),
        )
        .select_from(table)
        .outerjoin(active, on_active)
        .where(table.c.id.in_(_IDS))
    )
    if states is not None:
        attention = attention.outerjoin(state, state.c[key] == table.c.id)
    cal = subject.calibrations
    # The newest calibration and the newest check of each subject of a page, found through
    # the (<key>, created_at, id) and (<key>, action, id) indexes: a page costs the same
    # whether a subject has one calibration or a hundred thousand (bench/scale.py). Only the
    # columns the row shows: a calibration's stored request and result are kilobytes of JSON
    # each, and decoding 50 of them cost more than the rest of the page.
    calibrations = select(
        cal.c.id,
        cal.c[key].label("subject_id"),
        cal.c.status,
        cal.c.created_at,
        cal.c.result["quality"]["rms_mm"].as_float().label("rms_mm"),
    ).where(cal.c.id.in_(select(_newest_calibration(subject, "id")).where(table.c.id.in_(_IDS))))
    checks = None
    if subject.check_action is not None:
        newest = (
            select(func.max(_AUDIT.c.id))
            .where(subject.audit_key() == table.c.id, _AUDIT.c.action == subject.check_action)
            .correlate(table)
            .scalar_subquery()
        )
        checks = select(
            _AUDIT.c.id, subject.audit_key().label("subject_id"), _AUDIT.c.at, _AUDIT.c.details
        ).where(_AUDIT.c.id.in_(select(newest).where(table.c.id.in_(_IDS))))
    return Fleet(served, side, active, states, rules, columns, attention, calibrations, checks)


#: What a row's `controller` shows of the subject's controller state, in order.
_STATE_COLUMNS = (
    "state",
    "checked_at",
    "deviation_mm",
    "deviation_deg",
    "active_version",
    "target",
)


def _any(rules: Mapping[AnyAttentionCode, ColumnElement[bool]]) -> ColumnElement[bool]:
    """True when any rule holds (a rule whose subquery finds nothing counts as false)."""
    return or_(*(func.coalesce(rule, false()) for rule in rules.values()))


def _fleet_query(
    fleet: Fleet,
    *,
    cell: str | None,
    robot_id: str | None,
    q: str | None,
    status: str | None,
    attention: bool | None,
) -> Statement:
    subject = fleet.subject
    table, active = subject.table, fleet.active
    stmt = (
        select(*fleet.columns)
        .join(Robot, Robot.id == table.c.robot_id)
        .outerjoin(
            active,
            and_(active.c[subject.key] == table.c.id, active.c.version == table.c.active_version),
        )
        .where(table.c.archived_at.is_(None), Robot.archived_at.is_(None))
    )
    if cell is not None:
        stmt = stmt.where(Robot.cell == cell)
    if robot_id is not None:
        stmt = stmt.where(table.c.robot_id == robot_id)
    if q:
        prefix = q.lower().replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_") + "%"
        stmt = stmt.where(
            or_(
                func.lower(table.c.name).like(prefix, escape="\\"),
                func.lower(Robot.name).like(prefix, escape="\\"),
            )
        )
    if status is not None:
        stmt = stmt.where(_newest_calibration(subject, "status") == status)
    if attention is not None:
        stmt = stmt.where(_any(fleet.rules) if attention else ~_any(fleet.rules))
    return stmt


def list_fleet(
    session: Session,
    served: Served,
    *,
    cell: str | None,
    robot_id: str | None,
    q: str | None,
    status: str | None,
    limit: int,
    cursor: str | None,
    attention: bool | None = None,
) -> tuple[list[FleetRow], str | None]:
    """One page of a subject's fleet (rows of its `FleetSide.row`), oldest first; four
    queries per page whatever its size, each reading only the columns a row shows (rows, not
    ORM objects: a page is read-only). `attention`: only rows with (true) or without (false)
    an attention code. Only the robots in the acting key's cells."""
    fleet = fleet_of(served)
    table = fleet.subject.table
    moments = rule_moments(utcnow())
    stmt = in_scope(
        session,
        _fleet_query(fleet, cell=cell, robot_id=robot_id, q=q, status=status, attention=attention),
        Robot.id,
    )
    found, next_cursor = paginate_rows(
        session,
        stmt,
        created_col=table.c.created_at,
        id_col=table.c.id,
        limit=limit,
        cursor=cursor,
        params=moments if attention is not None else None,
    )
    ids = {"ids": [r.id for r in found]}
    last_cal = {c.subject_id: c for c in session.execute(fleet.calibrations, ids)}
    last_check = (
        {}
        if fleet.checks is None
        else {e.subject_id: e for e in session.execute(fleet.checks, ids)}
    )
    judged = _attention_of(session, fleet, ids["ids"], moments)
    side = fleet.side
    rows = [
        cast(
            "FleetRow",
            side.row(
                id=r.id,
                name=r.name,
                **{name: getattr(r, name) for name in side.columns},
                robot_id=r.robot_id,
                robot_name=r.robot_name,
                cell=r.cell,
                active_version=r.active_version,
                last_calibration=_last_calibration(last_cal.get(r.id)),
                last_check=_last_check(last_check.get(r.id)),
                position_mm=r.position_mm,
                quaternion=r.quaternion,
                drift=fleet_drift(r.drift),
                **judged[r.id],
            ),
        )
        for r in found
    ]
    return rows, next_cursor


def _attention_of(
    session: Session, fleet: Fleet, ids: list[str], moments: dict[str, datetime | int]
) -> dict[str, dict[str, object]]:
    """What the page's attention statement judges of each subject, in one statement: its
    attention codes, its controller state (when it has one) and its parts' fields."""
    if not ids:
        return {}
    codes = list(fleet.rules)
    judged: dict[str, dict[str, object]] = {}
    n_state = 0 if fleet.states is None else len(_STATE_COLUMNS)
    for row in session.execute(fleet.attention, {"ids": ids, **moments}):
        subject_id, *rest = row
        state, rest = rest[:n_state], rest[n_state:]
        fields: dict[str, object] = {"controller": _controller(state)}
        for part in fleet.side.parts:
            values, rest = rest[: len(part.columns)], rest[len(part.columns) :]
            fields[part.field] = part.read(values)
        fields["attention"] = [code for code, hit in zip(codes, rest, strict=True) if hit]
        judged[subject_id] = fields
    return judged


def _controller(values: Sequence[object]) -> FleetController | None:
    """A row's `controller` from the state's columns (`_STATE_COLUMNS`, "active_version" as
    the version compared with); None when the subject has no state."""
    if not values or values[0] is None:
        return None
    named = dict(zip(_STATE_COLUMNS, values, strict=True))
    named["version"] = named.pop("active_version")
    return FleetController.model_validate(named)


def _last_calibration(
    row: Row[str, str, str, datetime, float | None] | None,
) -> LastCalibration | None:
    if row is None:
        return None
    return LastCalibration(
        id=row.id, status=row.status, created_at=row.created_at, rms_mm=row.rms_mm
    )


def _last_check(row: Row[int, str | None, datetime, JsonObject | None] | None) -> LastCheck | None:
    if row is None:
        return None
    details = row.details or {}
    return LastCheck(
        id=str(row.id),
        within_tolerance=bool(details.get("within_tolerance")),
        distance_mm=float(details.get("distance_mm", 0.0)),
        created_at=row.at,
        verdict=details.get("verdict"),
        correction_version=_correction_version(details.get("correction")),
    )


#: The CSV's columns every subject's rows have, after the subject's own and its name.
_CSV_COMMON = (
    "robot",
    "cell",
    "active_version",
    "last_calibration_status",
    "last_calibration_rms_mm",
    "last_calibration_at",
    "last_check_within_tolerance",
    "last_check_distance_mm",
    "last_check_at",
    "attention",
    "active_x_mm",
    "active_y_mm",
    "active_z_mm",
    "active_qw",
    "active_qx",
    "active_qy",
    "active_qz",
    "controller_state",
    "controller_checked_at",
    "controller_deviation_mm",
    "controller_deviation_deg",
    "drift_rate_mm_per_month",
    "drift_sigma_mm_per_month",
    "drift_crosses_check_at",
)


def csv_columns(served: Served) -> tuple[str, ...]:
    """The CSV columns of a subject's fleet (GET /v1/tools with Accept: text/csv), in order:
    its id and name ("tool_id", "tool"), its own columns, the common ones, its parts'."""
    kind, side = served.subject.kind, fleet_of(served).side
    parts = tuple(name for part in side.parts for name in part.csv_names)
    return (f"{kind}_id", kind, *side.columns, *_CSV_COMMON, *parts)


def fleet_csv(served: Served, rows: Sequence[FleetRow]) -> str:
    """The rows as CSV, one line per subject, columns `csv_columns`."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\r\n")
    writer.writerow(csv_columns(served))
    writer.writerows(_csv_row(fleet_of(served).side, r) for r in rows)
    return out.getvalue()


def _csv_row(side: FleetSide, r: FleetRow) -> list[object]:
    return [
        r.id,
        r.name,
        *(_blank_or(getattr(r, name)) for name in side.columns),
        r.robot_name,
        r.cell or "",
        _blank_or(r.active_version),
        *_calibration_cells(r.last_calibration),
        *_check_cells(r.last_check),
        ";".join(r.attention),
        *_numbers(r.position_mm, 3, 3),
        *_numbers(r.quaternion, 4, 9),
        *_controller_cells(r.controller),
        *_drift_cells(r.drift),
        *(cell for part in side.parts for cell in part.csv_cells(getattr(r, part.field))),
    ]


def _blank_or(value: object) -> object:
    return "" if value is None else value


def _calibration_cells(cal: LastCalibration | None) -> list[str]:
    if cal is None:
        return ["", "", ""]
    rms = "" if cal.rms_mm is None else f"{cal.rms_mm:.3f}"
    return [cal.status, rms, cal.created_at.isoformat()]


def _check_cells(chk: LastCheck | None) -> list[str]:
    if chk is None:
        return ["", "", ""]
    return [str(chk.within_tolerance).lower(), f"{chk.distance_mm:.3f}", chk.created_at.isoformat()]


def _controller_cells(ctl: FleetController | None) -> list[str]:
    if ctl is None:
        return ["", "", "", ""]
    mm = "" if ctl.deviation_mm is None else f"{ctl.deviation_mm:.4f}"
    deg = "" if ctl.deviation_deg is None else f"{ctl.deviation_deg:.4f}"
    return [ctl.state, ctl.checked_at.isoformat(), mm, deg]


def _drift_cells(drift: FleetDrift | None) -> list[str]:
    if drift is None:
        return ["", "", ""]
    at = drift.crosses_check_at
    return [
        f"{drift.rate_mm_per_month:.4f}",
        f"{drift.sigma_mm_per_month:.4f}",
        "" if at is None else at.isoformat(),
    ]


def _numbers(values: Sequence[float] | None, n: int, decimals: int) -> list[str]:
    return [""] * n if values is None else [f"{v:.{decimals}f}" for v in values]


def list_checks(
    session: Session, subject: AnySubject, *, subject_id: str, limit: int, cursor: str | None
) -> tuple[list[CheckRecord], str | None]:
    """A subject's checks, newest first."""
    live = get_live(session, subject, subject_id)
    stmt = select(AuditEvent).where(
        subject.audit_key() == live.id, AuditEvent.action == subject.check_action
    )
    events, next_cursor = paginate_newest_first(
        session, stmt, id_col=AuditEvent.id, limit=limit, cursor=cursor
    )
    return [_check_record(subject, e) for e in events], next_cursor


def _correction_version(correction: object) -> int | None:
    """The version a recorded re-check corrected the TCP to (its `correction`), if any."""
    version = correction.get("version") if isinstance(correction, dict) else None
    return version if isinstance(version, int) else None


def _check_record(subject: AnySubject, event: AuditEvent) -> CheckRecord:
    """A check as recorded, naming its subject by the subject's key."""
    d = event.details or {}
    return CheckRecord.model_validate(
        {
            "id": str(event.id),
            subject.key: str(getattr(event, subject.key)),
            "version": d.get("version"),
            "reference_point_id": d.get("reference_point_id"),
            "deviation_mm": d.get("deviation_mm"),
            "deviation_flange_mm": d.get("deviation_flange_mm"),
            "distance_mm": float(d.get("distance_mm", 0.0)),
            "check_mm": d.get("check_mm"),
            "within_tolerance": bool(d.get("within_tolerance")),
            "summary": d.get("summary"),
            "verdict": d.get("verdict"),
            "correction_version": _correction_version(d.get("correction")),
            "checked_at": event.at,
            "checked_by": event.actor,
        }
    )
