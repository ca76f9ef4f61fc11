"""The fleet: every live tool of every robot with its last calibration and last check, and
a tool's checks read back (a check is recorded once, in the audit trail)."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from datetime import datetime
from typing import TypeVar

from sqlalchemy import Row, ScalarSelect, Select, func, or_, select
from sqlalchemy.orm import InstrumentedAttribute, Session

from app.helpers.pagination import paginate_newest_first, paginate_rows
from app.jsontypes import JsonObject
from app.models import AuditEvent, Calibration, Robot, Tool
from app.schemas.fleet import CSV_COLUMNS, CheckRecord, FleetTool, LastCalibration, LastCheck
from app.services.live import in_scope
from app.services.tools import get_tool

CHECK_ACTION = "tool.check"
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


#: The columns a fleet row shows of its tool and robot (created_at: the page's cursor).
_TOOL_COLUMNS = (
    Tool.id,
    Tool.name,
    Tool.slot,
    Tool.robot_id,
    Tool.active_version,
    Tool.created_at,
    Robot.name.label("robot_name"),
    Robot.cell,
)


def _fleet_query(
    *, cell: str | None, robot_id: str | None, q: str | None, status: str | None
) -> Select[str, str, int | None, str, int | None, datetime, str, str | None]:
    stmt = (
        select(*_TOOL_COLUMNS)
        .join(Robot, Robot.id == Tool.robot_id)
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
) -> tuple[list[FleetTool], str | None]:
    """One page of the fleet, oldest tool first; three queries per page whatever its size,
    each reading only the columns a row shows (rows, not ORM objects: a page is read-only)."""
    stmt = in_scope(
        session, _fleet_query(cell=cell, robot_id=robot_id, q=q, status=status), Robot.id
    )
    tools, next_cursor = paginate_rows(
        session, stmt, created_col=Tool.created_at, id_col=Tool.id, limit=limit, cursor=cursor
    )
    ids = [t.id for t in tools]
    last_cal = {c.tool_id: c for c in session.execute(_newest_calibrations(ids))}
    last_check = {e.tool_id: e for e in session.execute(_newest_checks(ids))}
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
        )
        for t in tools
    ]
    return rows, next_cursor


# The newest calibration and the newest check of each tool of a page, found through the
# (tool_id, created_at, id) and (tool_id, action, id) indexes: a page costs the same whether
# a tool has one calibration or a hundred thousand (bench/scale.py). Only the columns the row
# shows: a calibration's stored request and result are kilobytes of JSON each, and decoding
# 50 of them cost more than the rest of the page.
def _newest_calibrations(
    ids: list[str],
) -> Select[str, str, str, datetime, float | None]:
    newest = _newest_calibration(Calibration.id)
    return select(
        Calibration.id,
        Calibration.tool_id,
        Calibration.status,
        Calibration.created_at,
        Calibration.result["quality"]["rms_mm"].as_float().label("rms_mm"),
    ).where(Calibration.id.in_(select(newest).where(Tool.id.in_(ids))))


def _newest_checks(ids: list[str]) -> Select[int, str | None, datetime, JsonObject | None]:
    newest = (
        select(func.max(AuditEvent.id))
        .where(AuditEvent.tool_id == Tool.id, AuditEvent.action == CHECK_ACTION)
        .correlate(Tool)
        .scalar_subquery()
    )
    return select(AuditEvent.id, AuditEvent.tool_id, AuditEvent.at, AuditEvent.details).where(
        AuditEvent.id.in_(select(newest).where(Tool.id.in_(ids)))
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
    )


def fleet_csv(rows: Sequence[FleetTool]) -> str:
    """The rows as CSV, one line per tool, columns CSV_COLUMNS."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\r\n")
    writer.writerow(CSV_COLUMNS)
    for r in rows:
        cal, chk = r.last_calibration, r.last_check
        writer.writerow(
            [
                r.id,
                r.name,
                "" if r.slot is None else r.slot,
                r.robot_name,
                r.cell or "",
                "" if r.active_version is None else r.active_version,
                cal.status if cal else "",
                "" if cal is None or cal.rms_mm is None else f"{cal.rms_mm:.3f}",
                cal.created_at.isoformat() if cal else "",
                "" if chk is None else str(chk.within_tolerance).lower(),
                "" if chk is None else f"{chk.distance_mm:.3f}",
                chk.created_at.isoformat() if chk else "",
            ]
        )
    return out.getvalue()


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
        checked_at=event.at,
        checked_by=event.actor,
    )
