"""The fleet: every live tool of every robot with its active TCP, last calibration, last check
and why it needs attention, and a tool's checks read back (a check is recorded once, in the
audit trail)."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from datetime import datetime, timedelta
from typing import TypeVar

from sqlalchemy import (
    BindParameter,
    ColumnElement,
    Row,
    ScalarSelect,
    Select,
    and_,
    bindparam,
    false,
    func,
    or_,
    select,
)
from sqlalchemy.orm import InstrumentedAttribute, Session, aliased

from app.config import get_settings
from app.helpers.pagination import paginate_newest_first, paginate_rows
from app.jsontypes import JsonArray, JsonObject
from app.schemas.fleet import (
    CSV_COLUMNS,
    AttentionCode,
    CheckRecord,
    FleetController,
    FleetLive,
    FleetTool,
    LastCalibration,
    LastCheck,
)
from app.services.fleet.live import (
    AT_FLANGE,
    LIVE_CHECKED_AT,
    LIVE_NUMBER,
    LIVE_STATE,
    LIVE_TOOL_ID,
    LIVE_VERSION,
    UNKNOWN_TCP_HERE,
)
from app.services.tools.activation import CHECK_CORRECTION
from app.services.tools.drift import DRIFTING_WITHIN, crosses_by, fleet_drift
from app.services.tools.tools import get_tool
from app.services.visible import in_scope
from app.storage.models import (
    Activation,
    AuditEvent,
    Calibration,
    Robot,
    TcpVersion,
    Tool,
    ToolControllerState,
    utcnow,
)
from app.words import CHECK_ACTION, ToolState

T = TypeVar("T")


def _newest_calibration(column: InstrumentedAttribute[T]) -> ScalarSelect[T]:
    """`column` of the tool's newest calibration, correlated to Tool: a seek in the
    (tool_id, created_at, id) index whatever the length of the tool's history."""
    return (
        select(column)
        .where(Calibration.tool_id == Tool.id)
        .order_by(Calibration.created_at.desc(), Calibration.id.desc())
        .limit(1)
        .correlate(Tool)
        .scalar_subquery()
    )


def _newest_check(column: InstrumentedAttribute[T] | ColumnElement[T]) -> ScalarSelect[T]:
    """`column` of the tool's newest check, correlated to Tool: a seek in the
    (tool_id, action, id) index of the audit trail."""
    return (
        select(column)
        .where(AuditEvent.tool_id == Tool.id, AuditEvent.action == CHECK_ACTION)
        .order_by(AuditEvent.id.desc())
        .limit(1)
        .correlate(Tool)
        .scalar_subquery()
    )


#: The tool's active version, joined on the (tool_id, version) unique index.
_ACTIVE = aliased(TcpVersion, name="active_tcp")
OUT_OF_TOLERANCE = "out_of_tolerance"


#: A tool corrected by re-checks more than TCPCAL_CORRECTIONS_ALERT times in this long keeps
#: getting hit (`frequent_corrections`).
CORRECTIONS_WITHIN = timedelta(days=30)


def rule_moments(now: datetime) -> dict[str, datetime | int]:
    """The moments (and limits) the rules compare with at `now`: the parameters of `RULES`."""
    settings = get_settings()
    return {
        "stale_before": now - timedelta(days=settings.stale_days),
        "drifting_until": now + DRIFTING_WITHIN,
        "corrections_since": now - CORRECTIONS_WITHIN,
        "corrections_alert": settings.corrections_alert,
    }


def _rules(
    cutoff: ColumnElement[datetime],
    drifting_until: ColumnElement[datetime],
    corrections_since: ColumnElement[datetime],
    corrections_alert: ColumnElement[int],
) -> dict[AttentionCode, ColumnElement[bool]]:
    """The rule of each attention code, as a condition on a fleet row (Tool, its robot and
    its active version joined): the codes a row shows and `?attention=` are both these.
    Each is an index seek per tool, never a scan of calibrations, versions or checks."""
    return {
        "active_out_of_tolerance": _ACTIVE.status == OUT_OF_TOLERANCE,
        "last_calibration_out_of_tolerance": (
            _newest_calibration(Calibration.status) == OUT_OF_TOLERANCE
        ),
        # The newest check found the TCP out of tolerance and did not correct it (a re-check
        # that did is a new active version, judged by the other rules).
        "check_failed": and_(
            _newest_check(AuditEvent.details["within_tolerance"].as_boolean()) == false(),
            func.coalesce(_newest_check(AuditEvent.details["verdict"].as_string()), "").not_in(
                CORRECTED
            ),
        ),
        "no_active_version": Tool.active_version.is_(None),
        # Nothing done to the tool for stale_days: neither calibrated nor checked (a tool
        # registered less long ago is not stale yet).
        "stale": and_(
            func.coalesce(_newest_calibration(Calibration.created_at), Tool.created_at) < cutoff,
            func.coalesce(_newest_check(AuditEvent.at), Tool.created_at) < cutoff,
        ),
        # What the last reconcile or deployment found in the robot's controller.
        "controller_drifted": _controller_state() == "drifted",
        "controller_unreachable": _controller_state() == "unreachable",
        # The trend stored when a version or check was written projects out of check_mm.
        "drifting": crosses_by(drifting_until),
        # What the last reconcile round read of the TCP the robot moves by.
        "moving_by_stale_version": LIVE_STATE == "stale_version",
        # (a robot at its bare flange has no tool selected: no unknown TCP)
        "moving_by_unknown_tcp": and_(LIVE_STATE == "unknown", UNKNOWN_TCP_HERE, ~AT_FLANGE),
        # Corrected by re-checks more often than TCPCAL_CORRECTIONS_ALERT in 30 days.
        "frequent_corrections": _corrections_since(corrections_since) > corrections_alert,
    }


#: The verdicts of a check that corrected the TCP (app.services.checks.recheck).
CORRECTED = ("corrected", "deployment_failed")


def _corrections_since(since: ColumnElement[datetime]) -> ScalarSelect[int]:
    """How many activations of kind check_correction the tool has had since `since`,
    correlated to Tool: a seek in the (tool_id, id) index of its activations."""
    return (
        select(func.count(Activation.id))
        .where(
            Activation.tool_id == Tool.id,
            Activation.reason == CHECK_CORRECTION,
            Activation.activated_at >= since,
        )
        .correlate(Tool)
        .scalar_subquery()
    )


def _controller_state() -> ScalarSelect[ToolState]:
    """The tool's controller state, correlated to Tool (a primary-key seek)."""
    return (
        select(ToolControllerState.state)
        .where(ToolControllerState.tool_id == Tool.id)
        .correlate(Tool)
        .scalar_subquery()
    )


#: Every rule, built once: a fleet page's statements are executed with `rule_moments(now)`
#: as their parameters (building the rules' eight subqueries cost a page 2 ms of Python).
RULES = _rules(
    bindparam("stale_before"),
    bindparam("drifting_until"),
    bindparam("corrections_since"),
    bindparam("corrections_alert"),
)


def _any(rules: dict[AttentionCode, ColumnElement[bool]]) -> ColumnElement[bool]:
    """True when any rule holds (a rule whose subquery finds nothing counts as false)."""
    return or_(*(func.coalesce(rule, false()) for rule in rules.values()))


#: The columns a fleet row shows of its tool, robot and active version (created_at: the
#: page's cursor).
_TOOL_COLUMNS = (
    Tool.id,
    Tool.name,
    Tool.slot,
    Tool.robot_id,
    Tool.active_version,
    Tool.created_at,
    Robot.name.label("robot_name"),
    Robot.cell,
    _ACTIVE.position_mm,
    _ACTIVE.quaternion,
    Tool.drift,
)


def _fleet_query(
    *,
    cell: str | None,
    robot_id: str | None,
    q: str | None,
    status: str | None,
    attention: bool | None,
    rules: dict[AttentionCode, ColumnElement[bool]],
) -> Select[
    str,
    str,
    int | None,
    str,
    int | None,
    datetime,
    str,
    str | None,
    JsonArray,
    JsonArray,
    JsonObject | None,
]:
    stmt = (
        select(*_TOOL_COLUMNS)
        .join(Robot, Robot.id == Tool.robot_id)
        .outerjoin(
            _ACTIVE,
            and_(_ACTIVE.tool_id == Tool.id, _ACTIVE.version == Tool.active_version),
        )
        .where(Tool.archived_at.is_(None), Robot.archived_at.is_(None))
    )
    if cell is not None:
        stmt = stmt.where(Robot.cell == cell)
    if robot_id is not None:
        stmt = stmt.where(Tool.robot_id == robot_id)
    if q:
        prefix = q.lower().replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_") + "%"
        stmt = stmt.where(
            or_(
                func.lower(Tool.name).like(prefix, escape="\\"),
                func.lower(Robot.name).like(prefix, escape="\\"),
            )
        )
    if status is not None:
        stmt = stmt.where(_newest_calibration(Calibration.status) == status)
    if attention is not None:
        stmt = stmt.where(_any(rules) if attention else ~_any(rules))
    return stmt


def list_fleet(
    session: Session,
    *,
    cell: str | None,
    robot_id: str | None,
    q: str | None,
    status: str | None,
    limit: int,
    cursor: str | None,
    attention: bool | None = None,
) -> tuple[list[FleetTool], str | None]:
    """One page of the fleet, oldest tool first; four queries per page whatever its size,
    each reading only the columns a row shows (rows, not ORM objects: a page is read-only).
    `attention`: only rows with (true) or without (false) an attention code. Only the robots
    in the acting key's cells."""
    moments = rule_moments(utcnow())
    stmt = in_scope(
        session,
        _fleet_query(
            cell=cell, robot_id=robot_id, q=q, status=status, attention=attention, rules=RULES
        ),
        Robot.id,
    )
    tools, next_cursor = paginate_rows(
        session,
        stmt,
        created_col=Tool.created_at,
        id_col=Tool.id,
        limit=limit,
        cursor=cursor,
        params=moments if attention is not None else None,
    )
    ids = {"ids": [t.id for t in tools]}
    last_cal = {c.tool_id: c for c in session.execute(_NEWEST_CALIBRATIONS, ids)}
    last_check = {e.tool_id: e for e in session.execute(_NEWEST_CHECKS, ids)}
    codes, in_controller, live = _attention_of(session, ids["ids"], moments)
    rows = [
        FleetTool(
            id=t.id,
            name=t.name,
            slot=t.slot,
            robot_id=t.robot_id,
            robot_name=t.robot_name,
            cell=t.cell,
            active_version=t.active_version,
            last_calibration=_last_calibration(last_cal.get(t.id)),
            last_check=_last_check(last_check.get(t.id)),
            position_mm=t.position_mm,
            quaternion=t.quaternion,
            attention=codes.get(t.id, []),
            controller=in_controller.get(t.id),
            drift=fleet_drift(t.drift),
            live=live[t.id],
        )
        for t in tools
    ]
    return rows, next_cursor


#: The page's tools by id (an expanding parameter: the statements below are built once).
_IDS: BindParameter[list[str]] = bindparam("ids", expanding=True)
_ORDER: list[AttentionCode] = list(RULES)
#: The tool's controller state, joined on its primary key.
_STATE = aliased(ToolControllerState, name="controller_state")
#: Each rule of each tool of a page, evaluated by the database (the same conditions
#: `?attention=` filters on), and its controller state.
_ATTENTION = (
    select(
        Tool.id,
        _STATE.state,
        _STATE.checked_at,
        _STATE.deviation_mm,
        _STATE.deviation_deg,
        _STATE.active_version,
        _STATE.target,
        LIVE_STATE.label("live_state"),
        LIVE_VERSION.label("live_version"),
        LIVE_TOOL_ID.label("live_tool_id"),
        LIVE_CHECKED_AT.label("live_checked_at"),
        LIVE_NUMBER.label("live_number"),
        AT_FLANGE.label("live_flange"),
        *(RULES[code].label(f"rule_{i}") for i, code in enumerate(_ORDER)),
    )
    .outerjoin(
        _ACTIVE,
        and_(_ACTIVE.tool_id == Tool.id, _ACTIVE.version == Tool.active_version),
    )
    .outerjoin(_STATE, _STATE.tool_id == Tool.id)
    .where(Tool.id.in_(_IDS))
)


def _attention_of(
    session: Session, ids: list[str], moments: dict[str, datetime | int]
) -> tuple[dict[str, list[AttentionCode]], dict[str, FleetController], dict[str, FleetLive]]:
    """The attention codes of the page's tools, the controller state of each that has
    one and what its robot moves by, in one statement."""
    if not ids:
        return {}, {}, {}
    codes: dict[str, list[AttentionCode]] = {}
    states: dict[str, FleetController] = {}
    live: dict[str, FleetLive] = {}
    for row in session.execute(_ATTENTION, {"ids": ids, **moments}):
        tool_id, state, checked_at, deviation_mm, deviation_deg, version, target, *rest = row
        live_state, live_version, live_tool_id, live_checked_at, number, flange, *hits = rest
        codes[tool_id] = [code for code, hit in zip(_ORDER, hits, strict=True) if hit]
        live[tool_id] = FleetLive(
            state=live_state,
            version=live_version,
            tool_id=live_tool_id,
            checked_at=live_checked_at,
            number=None if live_state == "unread" else number,
            no_tool=live_state == "unknown" and bool(flange),
        )
        if state is not None:
            states[tool_id] = FleetController(
                state=state,
                checked_at=checked_at,
                deviation_mm=deviation_mm,
                deviation_deg=deviation_deg,
                version=version,
                target=target,
            )
    return codes, states, live


# The newest calibration and the newest check of each tool of a page, found through the
# (tool_id, created_at, id) and (tool_id, action, id) indexes: a page costs the same whether
# a tool has one calibration or a hundred thousand (bench/scale.py). Only the columns the row
# shows: a calibration's stored request and result are kilobytes of JSON each, and decoding
# 50 of them cost more than the rest of the page.
_NEWEST_CALIBRATIONS = select(
    Calibration.id,
    Calibration.tool_id,
    Calibration.status,
    Calibration.created_at,
    Calibration.result["quality"]["rms_mm"].as_float().label("rms_mm"),
).where(Calibration.id.in_(select(_newest_calibration(Calibration.id)).where(Tool.id.in_(_IDS))))
_NEWEST_CHECKS = select(AuditEvent.id, AuditEvent.tool_id, AuditEvent.at, AuditEvent.details).where(
    AuditEvent.id.in_(
        select(
            select(func.max(AuditEvent.id))
            .where(AuditEvent.tool_id == Tool.id, AuditEvent.action == CHECK_ACTION)
            .correlate(Tool)
            .scalar_subquery()
        ).where(Tool.id.in_(_IDS))
    )
)


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


def fleet_csv(rows: Sequence[FleetTool]) -> str:
    """The rows as CSV, one line per tool, columns CSV_COLUMNS."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\r\n")
    writer.writerow(CSV_COLUMNS)
    writer.writerows(_csv_row(r) for r in rows)
    return out.getvalue()


def _csv_row(r: FleetTool) -> list[object]:
    return [
        r.id,
        r.name,
        _blank_or(r.slot),
        r.robot_name,
        r.cell or "",
        _blank_or(r.active_version),
        *_calibration_cells(r.last_calibration),
        *_check_cells(r.last_check),
        ";".join(r.attention),
        *_numbers(r.position_mm, 3, 3),
        *_numbers(r.quaternion, 4, 9),
        *_controller_cells(r.controller),
        *_drift_cells(r),
        *_live_cells(r.live),
    ]


def _blank_or(value: int | None) -> object:
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


def _drift_cells(row: FleetTool) -> list[str]:
    drift = row.drift
    if drift is None:
        return ["", "", ""]
    at = drift.crosses_check_at
    return [
        f"{drift.rate_mm_per_month:.4f}",
        f"{drift.sigma_mm_per_month:.4f}",
        "" if at is None else at.isoformat(),
    ]


def _live_cells(live: FleetLive) -> list[str]:
    at = live.checked_at
    return [live.state, str(_blank_or(live.version)), "" if at is None else at.isoformat()]


def _numbers(values: Sequence[float] | None, n: int, decimals: int) -> list[str]:
    return [""] * n if values is None else [f"{v:.{decimals}f}" for v in values]


def list_checks(
    session: Session, *, tool_id: str, limit: int, cursor: str | None
) -> tuple[list[CheckRecord], str | None]:
    """A tool's checks, newest first."""
    tool = get_tool(session, tool_id)
    stmt = select(AuditEvent).where(
        AuditEvent.tool_id == tool.id, AuditEvent.action == CHECK_ACTION
    )
    events, next_cursor = paginate_newest_first(
        session, stmt, id_col=AuditEvent.id, limit=limit, cursor=cursor
    )
    return [_check_record(e) for e in events], next_cursor


def _correction_version(correction: object) -> int | None:
    """The version a recorded re-check corrected the TCP to (its `correction`), if any."""
    version = correction.get("version") if isinstance(correction, dict) else None
    return version if isinstance(version, int) else None


def _check_record(event: AuditEvent) -> CheckRecord:
    d = event.details or {}
    return CheckRecord(
        id=str(event.id),
        tool_id=str(event.tool_id),
        version=d.get("version"),
        reference_point_id=d.get("reference_point_id"),
        deviation_mm=d.get("deviation_mm"),
        deviation_flange_mm=d.get("deviation_flange_mm"),
        distance_mm=float(d.get("distance_mm", 0.0)),
        check_mm=d.get("check_mm"),
        within_tolerance=bool(d.get("within_tolerance")),
        summary=d.get("summary"),
        verdict=d.get("verdict"),
        correction_version=_correction_version(d.get("correction")),
        checked_at=event.at,
        checked_by=event.actor,
    )
