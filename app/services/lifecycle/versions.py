"""A subject's versions: numbering and activation (with history) under the subject's row lock,
and reading them back. Every function takes the subject's declaration
(app.services.lifecycle.subject.Subject) and never branches on which subject it is.

Core statements on the session's connection, not ORM objects: a calibration writes a version,
the subject's counters and two audit events, and the unit of work's pass over them cost more
than the statements (store 5 -> 1.6 ms in process). ORM objects of the same rows, where a
caller holds one, are expired after each write so that they read it back.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple, Protocol

from pydantic import BaseModel
from sqlalchemy import BindParameter, bindparam, insert, select, update
from sqlalchemy.orm import Session

from app.errors import Conflict, NoActiveVersion, NotFound, PreconditionFailed
from app.helpers.etags import if_match_ok
from app.jsontypes import JsonObject
from app.security.auth import Principal, cells_of
from app.services.audit import writes as audit
from app.services.lifecycle import drift
from app.services.lifecycle.subject import (
    ActivationT,
    AnySubject,
    Locked,
    Row,
    Subject,
    VersionT,
)
from app.services.visible import in_scope, live_or_404
from app.storage.db import DriverWrite, HeldRead
from app.storage.models import Robot, SubjectColumns, new_id, table_of, utcnow
from app.words import ActivationKind, AuditAction, Status, VersionSource

_ROBOT = table_of(Robot)


class _LockRow(NamedTuple):
    """A row of a subject's lock statement."""

    id: str
    robot_id: str
    name: str
    archived_at: datetime | None
    tolerance: JsonObject
    active_version: int | None
    last_version: int
    revision: int
    kinematics: JsonObject | None
    cell: str | None


#: The counters as a subject's writes set them (`_counters` gives their values).
_COUNTERS = ("active_version", "last_version", "revision", "updated_at")


class _Statements(NamedTuple):
    lock: HeldRead[_LockRow]
    save: DriverWrite
    save_with_drift: DriverWrite
    insert_version: DriverWrite
    insert_activation: DriverWrite


@functools.cache
def _statements(subject: AnySubject) -> _Statements:
    """A subject's statements, built once (each compiled once per dialect)."""
    table = subject.table
    counters: dict[str, BindParameter[object]] = {name: bindparam(name) for name in _COUNTERS}
    by_id = table.c.id == bindparam("subject_id")
    lock = HeldRead(
        _LockRow,
        select(
            table.c.id,
            table.c.robot_id,
            table.c.name,
            table.c.archived_at,
            table.c.tolerance,
            table.c.active_version,
            table.c.last_version,
            table.c.revision,
            _ROBOT.c.kinematics,
            _ROBOT.c.cell,
        )
        .join(_ROBOT, _ROBOT.c.id == table.c.robot_id)
        .where(by_id)
        .with_for_update(of=table),
    )
    trend: dict[str, BindParameter[object]] = {
        name: bindparam(name) for name in drift.StoredDrift._fields
    }
    return _Statements(
        lock,
        DriverWrite(update(table).where(by_id).values(**counters)),
        DriverWrite(update(table).where(by_id).values(**counters, **trend)),
        DriverWrite(insert(subject.versions)),
        DriverWrite(insert(subject.activations)),
    )


def lock(session: Session, subject: AnySubject, subject_id: str) -> Locked:
    """Lock a live subject's row for the rest of the transaction (serialises its versions), or
    404. Pending ORM changes are written first, so that the lock reads them."""
    session.flush()
    row = _statements(subject).lock.one_or_none_in(session, subject_id=subject_id)
    cells = cells_of(session)
    if row is not None and cells is not None and row.cell not in cells:
        row = None  # a subject of another cell's robot: as if absent
    row = live_or_404(row, subject.kind, subject_id)
    return Locked(
        row.id,
        row.robot_id,
        row.name,
        row.tolerance,
        row.active_version,
        row.last_version,
        row.revision,
        row.kinematics,
    )


class Revised(Protocol):
    """A subject as its ETag sees it (the ORM row, or one read under its lock)."""

    @property
    def id(self) -> str: ...
    @property
    def revision(self) -> int: ...


def etag(row: Revised) -> str:
    """Strong ETag of a subject; changes with every change to it, its versions or activation."""
    digest = hashlib.sha256(f"{row.id}:{row.revision}".encode()).hexdigest()[:20]
    return f'"{digest}"'


def check_if_match(subject: AnySubject, row: Revised, if_match: str | None) -> None:
    """412 when an If-Match header does not name the subject's current ETag."""
    if if_match_ok(if_match, etag(row)):
        return
    raise PreconditionFailed(
        f"{subject.kind} {row.id} changed since you read it: its ETag is now {etag(row)}; "
        "read it again and retry",
        headers={"ETag": etag(row)},
    )


@dataclass(frozen=True)
class Taken:
    """A subject's words for a name (`name`) or a slot (`slot`) another of its robot's live
    ones has (check_unique): str.format templates of robot_id, name, slot and other (the
    other's id)."""

    name: str
    slot: str


def check_unique(
    session: Session,
    subject: AnySubject,
    taken: Taken,
    robot_id: str,
    fields: Mapping[str, object],
    *,
    except_id: str | None = None,
) -> None:
    """409 at body.name or body.slot when another live subject of the robot (not `except_id`)
    has the name or the slot `fields` give (a body, a PATCH's changes: absent or null is not
    checked), said in the subject's words."""
    name, slot = fields.get("name"), fields.get("slot")
    table = subject.table
    live = select(table.c.id).where(table.c.robot_id == robot_id, table.c.archived_at.is_(None))
    if except_id:
        live = live.where(table.c.id != except_id)
    other = None if name is None else session.scalars(live.where(table.c.name == name)).first()
    words = {"robot_id": robot_id, "name": name, "slot": slot, "other": other}
    if other is not None:
        raise Conflict(taken.name.format(**words), loc=("body", "name"), msg="already taken")
    if slot is not None and session.scalars(live.where(table.c.slot == slot)).first():
        raise Conflict(taken.slot.format(**words), loc=("body", "slot"), msg="already taken")


def patched(body: BaseModel) -> JsonObject:
    """The fields a PATCH body gives (JSON merge patch); a null name is no change."""
    changes = body.model_dump(exclude_unset=True)
    if changes.get("name", "") is None:
        changes.pop("name")
    return changes


@dataclass(frozen=True)
class Patch:
    """What a subject's PATCH writes (apply_update): its audit event's `action`, the fields
    whose old and new values the event shows (`shown`: the others by name), and its stored
    tolerance with the defaults filled in (`tolerance`)."""

    action: AuditAction
    shown: Collection[str]
    tolerance: Callable[[JsonObject | None], BaseModel]


def apply_update(
    session: Session,
    subject: AnySubject,
    patch: Patch,
    row: SubjectColumns,
    changes: JsonObject,
    *,
    actor: Principal,
) -> None:
    """Write a PATCH's checked `changes` to a subject's row, with its audit event. The
    tolerance merges with what is stored, its defaults filled in: {"tolerance":
    {"max_rms_mm": 0.2}} changes that one limit and keeps the others, and a null one changes
    nothing; a changed tolerance refits the drift trend (another check_mm, another
    projection)."""
    tolerance = patch.tolerance
    if "tolerance" in changes:
        if changes["tolerance"] is None:
            changes.pop("tolerance")
        else:
            changes["tolerance"] = {
                **tolerance(row.tolerance).model_dump(),
                **changes["tolerance"],
            }
    details = audit.changes(
        row,
        changes,
        values_of=patch.shown,
        before={"tolerance": tolerance(row.tolerance).model_dump()},
    )
    for key, value in changes.items():
        setattr(row, key, value)
    if "tolerance" in changes:
        row.drift, row.drift_crosses_at = drift.fit_drift(session, subject, row)
    row.updated_at = utcnow()
    row.revision += 1
    audit.record_about(
        session, subject, row.id, row.robot_id, actor=actor, action=patch.action, details=details
    )


def get_live(
    session: Session, subject: Subject[Row, VersionT, ActivationT], subject_id: str
) -> Row:
    """A live subject's ORM row, or 404 (/not-found, or /archived)."""
    model = subject.model
    stmt = select(model).where(subject.table.c.id == subject_id)
    stmt = in_scope(session, stmt, subject.table.c.robot_id)
    return live_or_404(session.scalars(stmt).one_or_none(), subject.kind, subject_id)


def _save(session: Session, subject: AnySubject, locked: Locked, now: datetime) -> None:
    """Write the locked subject's counters; an ORM copy of the row reads them back."""
    _statements(subject).save.execute(session, [_counters(locked, now)])
    _expire(session, subject, locked)


def _counters(locked: Locked, now: datetime) -> dict[str, object]:
    return {
        "subject_id": locked.id,
        "active_version": locked.active_version,
        "last_version": locked.last_version,
        "revision": locked.revision,
        "updated_at": now,
    }


def _expire(session: Session, subject: AnySubject, locked: Locked) -> None:
    cached = session.identity_map.get(session.identity_key(subject.model, locked.id))
    if cached is not None:
        session.expire(cached)


def save_deferred(session: Session, subject: AnySubject, locked: Locked) -> None:
    """Write what deferred writes changed: the subject's counters and its drift trend, refitted
    once for them all, in one UPDATE (a calibration's version and its activation each wrote
    the row, and each refitted a trend that the next one replaced)."""
    if locked.updated_at is None:
        return
    fitted = drift.fit_drift(session, subject, locked)
    row = {**_counters(locked, locked.updated_at), **fitted._asdict()}
    _statements(subject).save_with_drift.execute(session, [row])
    locked.updated_at = None
    _expire(session, subject, locked)


def add_version(
    session: Session,
    subject: AnySubject,
    *,
    locked: Locked,
    position_mm: Sequence[float],
    quaternion: Sequence[float],
    source: VersionSource,
    status: Status,
    calibration_id: str | None,
    note: str | None,
    actor: Principal,
    created_at: datetime | None = None,
    deferred: bool = False,
) -> int:
    """Append version n+1 of a subject locked with `lock`; its number. `created_at`: the
    time of the calibration it comes from (default now). The counters and the drift trend
    are written now, or with `deferred` by the caller's `save_deferred` once it has written
    everything of the transaction."""
    now = created_at or utcnow()
    locked.last_version = locked.next_version
    locked.revision += 1
    _statements(subject).insert_version.execute(
        session,
        [
            {
                "id": new_id(),
                subject.key: locked.id,
                "version": locked.last_version,
                "position_mm": [float(v) for v in position_mm],
                "quaternion": [float(v) for v in quaternion],
                "source": source,
                "status": status,
                "calibration_id": calibration_id,
                "note": note,
                "created_at": now,
                "created_by": actor.name,
            }
        ],
    )
    _written(session, subject, locked, now, deferred)
    audit.record(
        session,
        actor=actor,
        action="version.create",
        resource_type=subject.kind,
        resource_id=locked.id,
        robot_id=locked.robot_id,
        about={subject.key: locked.id},
        version=locked.last_version,
        details={"source": source, "status": status},
    )
    if not deferred:
        _refresh_drift(session, subject, locked)
    return locked.last_version


def _written(
    session: Session, subject: AnySubject, locked: Locked, now: datetime, deferred: bool
) -> None:
    """The counters written now, or marked for the caller's `save_deferred`."""
    if deferred:
        locked.updated_at = now
    else:
        _save(session, subject, locked, now)


def activate(
    session: Session,
    subject: AnySubject,
    *,
    locked: Locked,
    version: int,
    reason: ActivationKind,
    actor: Principal,
    reason_text: str | None = None,
    action: AuditAction = "version.activate",
    details: JsonObject | None = None,
    deferred: bool = False,
) -> None:
    """Make `version` the active one and record who did it, when and why (a subject locked
    with `lock`). `reason` is the kind (explicit, forced, rollback, calibration:auto, ...),
    `reason_text` the person's own words; both go into the activation history. The audit
    event (`action`, with `details` added) carries the kind as `kind` and the why as
    `reason`: the person's words when given, else the kind. `deferred`: the counters and
    the drift trend are written by the caller's `save_deferred`."""
    now = utcnow()
    previous, locked.active_version = locked.active_version, version
    locked.revision += 1
    _statements(subject).insert_activation.execute(
        session,
        [
            {
                subject.key: locked.id,
                "version": version,
                "previous_version": previous,
                "reason": reason,
                "reason_text": reason_text,
                "activated_by": actor.name,
                "activated_at": now,
            }
        ],
    )
    _written(session, subject, locked, now, deferred)
    event: JsonObject = {
        "version": version,
        "previous_version": previous,
        "kind": reason,
        "reason": reason if reason_text is None else reason_text,
    }
    audit.record_about(
        session,
        subject,
        locked.id,
        locked.robot_id,
        actor=actor,
        action=action,
        version=version,
        details={**event, **(details or {})},
    )
    if not deferred:
        _refresh_drift(session, subject, locked)


def _refresh_drift(session: Session, subject: AnySubject, locked: Locked) -> None:
    """The drift trend after a new version or activation (a new version is a new point of the
    series; another active version, another reference and set of checks)."""
    drift.store_drift(session, subject, locked.id, drift.fit_drift(session, subject, locked))


def get_version(
    session: Session, subject: Subject[Row, VersionT, ActivationT], *, subject_id: str, version: int
) -> VersionT:
    """One version of a live subject, or 404."""
    get_live(session, subject, subject_id)
    row = session.scalars(
        select(subject.version_model).where(
            subject.version_key() == subject_id, subject.versions.c.version == version
        )
    ).one_or_none()
    if row is None:
        raise NotFound(f"{subject.kind} {subject_id} has no version {version}")
    return row


def list_versions(
    session: Session, subject: Subject[Row, VersionT, ActivationT], *, subject_id: str
) -> tuple[Row, list[VersionT], list[ActivationT]]:
    """Every version of a subject (oldest first) and its activation history."""
    row = get_live(session, subject, subject_id)
    versions = list(
        session.scalars(
            select(subject.version_model)
            .where(subject.version_key() == subject_id)
            .order_by(subject.versions.c.version)
        )
    )
    history = list(
        session.scalars(
            select(subject.activation_model)
            .where(subject.activation_key() == subject_id)
            .order_by(subject.activations.c.id)
        )
    )
    return row, versions, history


def active_version_row(
    session: Session, subject: Subject[Row, VersionT, ActivationT], row: Row
) -> VersionT:
    """The active version of a subject, or 404 /no-active-version."""
    if row.active_version is None:
        raise NoActiveVersion(
            f"{subject.kind} {row.id} ({row.name}) has no active {subject.value} version yet"
        )
    return session.scalars(
        select(subject.version_model).where(
            subject.version_key() == row.id, subject.versions.c.version == row.active_version
        )
    ).one()
