"""The audit trail: one row per write, with who and when."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import event as sa_event
from sqlalchemy import insert
from sqlalchemy.orm import Session

from app.auth import Principal
from app.db import DriverWrite
from app.jsontypes import JsonObject
from app.logs import events_logger
from app.models import AuditEvent, table_of, utcnow
from app.services import outbox


def record(
    session: Session,
    *,
    actor: Principal,
    action: str,
    resource_type: str,
    resource_id: str,
    robot_id: str | None = None,
    tool_id: str | None = None,
    details: JsonObject | None = None,
) -> None:
    """Append an audit event to the current transaction: written when it commits, with every
    other event of the transaction in one statement, and logged once it has committed."""
    session.info.setdefault(_ROWS, []).append(
        row(
            at=utcnow(),  # now, not when the transaction commits
            actor=actor.name,
            api_key_id=actor.key_id,
            action=action,
            resource_type=resource_type,
            resource_id=resource_id,
            robot_id=robot_id,
            tool_id=tool_id,
            details=details,
        )
    )
    event: JsonObject = {
        "actor": actor.name,
        "resource_type": resource_type,
        "resource_id": resource_id,
        "robot_id": robot_id,
        "tool_id": tool_id,
        **(details or {}),
    }
    session.info.setdefault(_PENDING, []).append((action, event))


def row(
    *,
    at: datetime,
    actor: str,
    api_key_id: str | None,
    action: str,
    resource_type: str,
    resource_id: str,
    robot_id: str | None,
    tool_id: str | None,
    details: JsonObject | None,
) -> dict[str, object]:
    """An audit_events row as inserted (also by bench/scale.py's bulk seeding)."""
    return {
        "at": at,
        "actor": actor,
        "api_key_id": api_key_id,
        "action": action,
        "resource_type": resource_type,
        "resource_id": resource_id,
        "robot_id": robot_id,
        "tool_id": tool_id,
        "details": details,
    }


#: Rows of the open transaction, inserted as it commits (one executemany: a calibration
#: writes two, and an ORM object per row cost a unit-of-work pass each).
_ROWS = "tcpcal.audit_rows"
#: Events of the open transaction, logged once it commits (a rolled-back one never happened).
_PENDING = "tcpcal.audit_events"
_INSERT = DriverWrite(insert(table_of(AuditEvent)))


@sa_event.listens_for(Session, "before_commit")
def _write_rows(session: Session) -> None:
    rows = session.info.pop(_ROWS, None)
    if rows:
        _INSERT.execute(session, rows)
        outbox.write(session, rows)  # the plant hears of the same changes, in this transaction


@sa_event.listens_for(Session, "after_commit")
def _log_committed(session: Session) -> None:
    for action, fields in session.info.pop(_PENDING, []):
        events_logger().info(action, **fields)


@sa_event.listens_for(Session, "after_rollback")
def _forget_rolled_back(session: Session) -> None:
    session.info.pop(_ROWS, None)
    session.info.pop(_PENDING, None)
