"""The audit trail: one row per write, with who and when."""

from __future__ import annotations

from collections.abc import Collection, Mapping
from datetime import datetime
from typing import Protocol, TypeVar

from sqlalchemy import event as sa_event
from sqlalchemy import insert
from sqlalchemy.orm import Session

from app.jsontypes import JsonObject
from app.logs import REQUEST_ID, events_logger
from app.security.auth import Principal
from app.services.audit import outbox
from app.storage.db import DriverWrite
from app.storage.models import SUBJECT_KEYS, AuditEvent, table_of, utcnow
from app.words import AuditAction, ResourceType


def record(
    session: Session,
    *,
    actor: Principal,
    action: AuditAction,
    resource_type: ResourceType,
    resource_id: str,
    robot_id: str | None = None,
    tool_id: str | None = None,
    version: int | None = None,
    details: JsonObject | None = None,
    about: Mapping[str, str] | None = None,
) -> None:
    """Append an audit event to the current transaction: written when it commits, with every
    other event of the transaction in one statement, and logged once it has committed. Its
    request id is the one the access log line carries (app.logs.REQUEST_ID: set by the
    request middleware, and by a solver process for the calibration it stores). `about`:
    the calibrated subject the event concerns, by the column that names it
    (app.services.lifecycle.subject.Subject.key: {"tool_id": ...})."""
    request_id = REQUEST_ID.get()
    ids = {"tool_id": tool_id, **(about or {})}
    session.info.setdefault(_ROWS, []).append(
        {
            **row(
                at=utcnow(),  # now, not when the transaction commits
                actor=actor.name,
                api_key_id=actor.key_id,
                action=action,
                resource_type=resource_type,
                resource_id=resource_id,
                robot_id=robot_id,
                tool_id=tool_id,
                version=version,
                request_id=request_id,
                details=details,
            ),
            # every subject's column, so that the transaction's rows insert as one executemany
            **dict.fromkeys(SUBJECT_KEYS),
            **ids,
        }
    )
    event: JsonObject = {
        "actor": actor.name,
        "resource_type": resource_type,
        "resource_id": resource_id,
        "robot_id": robot_id,
        **ids,
        "version": version,
        **(details or {}),
    }
    session.info.setdefault(_PENDING, []).append((action, event))


class Named(Protocol):
    """A calibrated subject as its audit events name it (app.services.lifecycle.subject.Subject):
    its kind, their resource type, and its key, the column naming it ("tool_id")."""

    @property
    def kind(self) -> ResourceType: ...
    @property
    def key(self) -> str: ...


def record_about(
    session: Session,
    subject: Named,
    subject_id: str,
    robot_id: str,
    *,
    actor: Principal,
    action: AuditAction,
    details: JsonObject,
    version: int | None = None,
) -> None:
    """`record` an event about one subject of a robot: its kind the resource type, the subject
    the resource, named by its key."""
    record(
        session,
        actor=actor,
        action=action,
        resource_type=subject.kind,
        resource_id=subject_id,
        robot_id=robot_id,
        about={subject.key: subject_id},
        version=version,
        details=details,
    )


class _Created(Protocol):
    """A new row with an id: made in Python (a uuid), or by the database (a deployment's
    sequence number, known once the row is flushed)."""

    @property
    def id(self) -> str | int: ...


Created = TypeVar("Created", bound=_Created)


def add_created(
    session: Session,
    new: Created,
    *,
    actor: Principal,
    action: AuditAction,
    resource_type: ResourceType,
    robot_id: str | None = None,
    tool_id: str | None = None,
    details: JsonObject | None = None,
    about: Mapping[str, str] | None = None,
) -> Created:
    """Insert a new resource's row and its audit event in the current transaction: the one
    way every service creates what it audits (the row is flushed, so its id and defaults
    are set and a unique constraint fails here, before the event). `about`: the calibrated
    subject it concerns by its key, as for `record`."""
    session.add(new)
    session.flush()
    record(
        session,
        actor=actor,
        action=action,
        resource_type=resource_type,
        resource_id=str(new.id),
        robot_id=robot_id,
        tool_id=tool_id,
        details=details,
        about=about,
    )
    return new


def changes(
    row: object,
    new: Mapping[str, object],
    *,
    values_of: Collection[str],
    before: Mapping[str, object] | None = None,
) -> JsonObject:
    """The details of a PATCH's audit event: every field it changed, and the old and new
    values of those in `values_of` (the others, such as a robot's model of kilobytes, by
    name). `before`: old values to show instead of the row's (a tolerance with its
    defaults filled in)."""
    shown = [k for k in sorted(new) if k in values_of]
    old = {k: (before[k] if before and k in before else getattr(row, k)) for k in shown}
    return {"changed": sorted(new), "from": old, "to": {k: new[k] for k in shown}}


def row(
    *,
    at: datetime,
    actor: str,
    api_key_id: str | None,
    action: AuditAction,
    resource_type: ResourceType,
    resource_id: str,
    robot_id: str | None,
    tool_id: str | None,
    details: JsonObject | None,
    version: int | None = None,
    request_id: str | None = None,
) -> dict[str, object]:
    """An audit_events row as inserted (also by bench/scale.py's bulk seeding)."""
    return {
        "version": version,
        "request_id": request_id,
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
