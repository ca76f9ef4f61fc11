"""Each subject's controller state (in sync, drifted, unreachable, no active version, not
live) as the last reconcile or deployment saw it, in the subject's states table
(app.services.lifecycle.subject.Subject.state_model); a change of state is an audit event,
once."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple, Protocol, cast

from sqlalchemy import Table, bindparam, insert, select, update
from sqlalchemy.orm import Session

from app.jsontypes import JsonObject
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.lifecycle.subject import AnySubject, Held
from app.storage.db import DriverWrite, HeldRead
from app.storage.models import Base
from app.words import AuditAction, ToolState

#: States whose start is an audit event `controller.<state>` (and counted in /metrics), with
#: that event's action.
EVENT_ACTIONS: dict[ToolState, AuditAction] = {
    "in_sync": "controller.in_sync",
    "drifted": "controller.drifted",
    "unreachable": "controller.unreachable",
}
#: How bad each state is, for a robot's state (the worst of its tools'): an index into
#: ROBOT_STATES.
SEVERITY: dict[ToolState, int] = {
    "in_sync": 0,
    "no_active_version": 0,
    "not_live": 0,
    "drifted": 1,
    "unreachable": 2,
}


class StateRow(Protocol):
    """A subject's controller state row as the controller code reads and writes it (a
    models.ToolControllerState)."""

    robot_id: str
    state: ToolState
    since: datetime
    checked_at: datetime
    target: str | None
    controller: JsonObject | None
    active_version: int | None
    deviation_mm: float | None
    deviation_deg: float | None
    error: str | None


def frame_json(data: Held | None) -> JsonObject | None:
    """A frame as stored and served: {"position_mm", "quaternion"}."""
    if data is None:
        return None
    return {"position_mm": list(data.position_mm), "quaternion": list(data.quaternion)}


@dataclass(frozen=True)
class Observation:
    """What one look at the controller found for one subject (`subject_id` of `subject`)."""

    subject: AnySubject
    subject_id: str
    robot_id: str
    state: ToolState
    target: str | None
    controller: JsonObject | None
    active_version: int | None
    deviation_mm: float | None
    deviation_deg: float | None
    error: str | None


def _state_model(subject: AnySubject) -> type[Base]:
    model = subject.state_model
    assert model is not None, f"the {subject.kind} declares no controller states"
    return model


class _Found(NamedTuple):
    """A subject's stored state and since (both None before its first)."""

    state: ToolState | None
    since: datetime | None


@functools.cache
def _locked_state(subject: AnySubject) -> HeldRead[_Found]:
    """The subject's row locked with its state and since (built once a kind: a round runs
    it for every subject of every robot, on the driver's cursor), the subject a bound
    parameter."""
    table = subject.table
    states = cast(Table, _state_model(subject).__table__)
    return HeldRead(
        _Found,
        select(states.c.state, states.c.since)
        .select_from(table.outerjoin(states, states.c[subject.key] == table.c.id))
        .where(table.c.id == bindparam("subject_id"))
        .with_for_update(of=table),
    )


@functools.cache
def _writes(subject: AnySubject) -> tuple[DriverWrite, DriverWrite]:
    """The subject's state row inserted, and updated (the subject bound as `subject`): on
    the driver's cursor, built once a kind. Through Session.execute a look's UPDATE, built
    anew each time, was a third of what storing a robot's round cost the watcher. A look
    writes every column but the subject's key."""
    states = cast(Table, _state_model(subject).__table__)
    written = [c.name for c in states.c if c.name != subject.key]
    updated = update(states).where(states.c[subject.key] == bindparam("subject"))
    return DriverWrite(insert(states)), DriverWrite(
        updated.values({c: bindparam(c) for c in written})
    )


def observe(
    session: Session, seen: Observation, *, at: datetime, actor: Principal
) -> tuple[datetime, bool]:
    """Store what was seen; (since when the subject is in its state, whether the state
    changed). The subject's row is locked as its state row is read (one statement), so two
    instances looking at once record one change, not two. Statements on the driver's cursor
    (a round stores one a subject of every robot): an ORM copy of the row in the session is
    expired."""
    subject = seen.subject
    model = _state_model(subject)
    found = _locked_state(subject).one_or_none_in(session, subject_id=seen.subject_id)
    previous = None if found is None or found.since is None else found.state
    changed = previous is None or previous != seen.state
    since = at if changed or found is None or found.since is None else found.since
    values: dict[str, object] = {
        "robot_id": seen.robot_id,
        "state": seen.state,
        "since": since,
        "checked_at": at,
        "target": seen.target,
        "controller": seen.controller,
        "active_version": seen.active_version,
        "deviation_mm": seen.deviation_mm,
        "deviation_deg": seen.deviation_deg,
        "error": seen.error,
    }
    inserted, updated = _writes(subject)
    if previous is None:
        inserted.execute(session, [{subject.key: seen.subject_id, **values}])
    else:
        updated.execute(session, [{"subject": seen.subject_id, **values}])
    copy = session.identity_map.get(session.identity_key(model, seen.subject_id))
    if copy is not None:
        session.expire(copy)
    action = EVENT_ACTIONS.get(seen.state) if changed else None
    if action is not None:
        _record_change(session, seen, previous, action, actor)
    return since, action is not None


def _record_change(
    session: Session,
    seen: Observation,
    previous: ToolState | None,
    action: AuditAction,
    actor: Principal,
) -> None:
    audit.record_about(
        session,
        seen.subject,
        seen.subject_id,
        seen.robot_id,
        actor=actor,
        action=action,
        version=seen.active_version,
        details={
            "previous_state": previous,
            "target": seen.target,
            "version": seen.active_version,
            "controller": seen.controller,
            "deviation_mm": seen.deviation_mm,
            "deviation_deg": seen.deviation_deg,
            "error": seen.error,
        },
    )


def not_live(
    subject: AnySubject, subject_id: str, robot_id: str, target: str | None, version: int | None
) -> Observation:
    """A subject of a robot with one live one of its kind (a `live` scope protocol: a tool of
    `ur_rtde`, `techman`) that is not the one deployed to it last: not judged against what
    the controller holds."""
    return Observation(
        subject=subject,
        subject_id=subject_id,
        robot_id=robot_id,
        state="not_live",
        target=target,
        controller=None,
        active_version=version,
        deviation_mm=None,
        deviation_deg=None,
        error=None,
    )


def others_not_live(
    session: Session,
    *,
    subject: AnySubject,
    robot_id: str,
    live_id: str,
    target: str,
    at: datetime,
    actor: Principal,
) -> None:
    """A `live` scope deployment made `live_id` the robot's one live subject of its kind: its
    other live ones are `not_live` from then on (the reconcile rounds judge the one deployed
    last)."""
    table = subject.table
    others = session.execute(
        select(table.c.id, table.c.active_version)
        .where(table.c.robot_id == robot_id, table.c.archived_at.is_(None), table.c.id != live_id)
        .order_by(table.c.id)
    ).all()
    for other_id, version in others:
        seen = not_live(subject, other_id, robot_id, target, version)
        observe(session, seen, at=at, actor=actor)
