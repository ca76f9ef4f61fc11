"""The hot read of any subject: the caller's key, the subject and its active version in one
statement, and the strong ETag of what is served from it.

What a fleet of cell controllers polls (a tool's GET /v1/tools/{id}/tcp as JSON or as its
controller's file): one statement on the thread's held connection (app.storage.db.HeldRead),
no ORM, no transaction around it, nothing cached, so a revoked key or a new activation is
seen by the very next request. The statement is built once per subject from its declaration:
its table and versions' table, and `served_detail`, the one JSON column of its own that it
serves (a tool's load).
"""

from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple

from sqlalchemy import JSON, Engine, and_, bindparam, cast, null, select

from app.errors import Archived, NoActiveVersion, NotFound
from app.jsontypes import JsonArray, JsonObject
from app.scopes import Scope
from app.security.auth import Principal, admit, digest_of
from app.services.lifecycle.subject import AnySubject
from app.storage.db import HeldRead
from app.storage.models import ApiKey, Robot, table_of
from app.words import VersionSource


class HotRow(NamedTuple):
    """A row of a hot read: the key under its own column names (what `admit` reads), then the
    subject, its robot's cell and its active version, each None when the subject is unknown
    or has no active version (outer joins)."""

    id: str
    name: str
    scope: Scope
    key_hash: str
    revoked_at: datetime | None
    cells: JsonArray | None
    cell: str | None
    subject_id: str | None
    robot_id: str | None
    subject_name: str | None
    slot: int | None
    detail: JsonObject | None
    controller_symbol: str | None
    archived_at: datetime | None
    version: int | None
    position_mm: JsonArray | None
    quaternion: JsonArray | None
    source: VersionSource | None
    created_at: datetime | None
    created_by: str | None


_KEY, _ROBOT = table_of(ApiKey), table_of(Robot)


@functools.cache
def hot_read(subject: AnySubject) -> HeldRead[HotRow]:
    """The subject's hot read, built once (compiled once per dialect); its binds are
    `digest` (of the key) and `subject_id`."""
    table, versions = subject.table, subject.versions
    detail = cast(null(), JSON) if subject.served_detail is None else table.c[subject.served_detail]
    return HeldRead(
        HotRow,
        select(
            _KEY.c.id,
            _KEY.c.name,
            _KEY.c.scope,
            _KEY.c.key_hash,
            _KEY.c.revoked_at,
            _KEY.c.cells,
            _ROBOT.c.cell,
            table.c.id.label("subject_id"),
            table.c.robot_id,
            table.c.name.label("subject_name"),
            table.c.slot,
            detail.label("detail"),
            table.c.controller_symbol,
            table.c.archived_at,
            versions.c.version,
            versions.c.position_mm,
            versions.c.quaternion,
            versions.c.source,
            versions.c.created_at,
            versions.c.created_by,
        )
        .select_from(_KEY)
        .outerjoin(table, table.c.id == bindparam("subject_id"))
        .outerjoin(_ROBOT, _ROBOT.c.id == table.c.robot_id)
        .outerjoin(
            versions,
            and_(
                subject.version_key() == table.c.id,
                versions.c.version == table.c.active_version,
            ),
        )
        .where(_KEY.c.key_hash == bindparam("digest")),
    )


# Plain records, not ORM objects: an instrumented __init__ cost 50 us a request here.
@dataclass(frozen=True, slots=True)
class HotVersion:
    """The active version of a hot read (an app.services.tools.controller_text.ServedVersion),
    and who made it."""

    version: int
    position_mm: JsonArray
    quaternion: JsonArray
    source: VersionSource
    created_at: datetime
    created_by: str


def read_for_key(
    engine: Engine, subject: AnySubject, authorization: str | None, subject_id: str
) -> tuple[Principal, HotRow]:
    """(who, the row) for the caller behind `authorization` and a subject: 401 for no key or
    an unknown or revoked one, 403 for too small a scope (a key comes before the subject)."""
    digest = digest_of(authorization)
    found = hot_read(subject).one_or_none(engine, digest=digest, subject_id=subject_id)
    principal = admit(found, digest, required="read")
    assert found is not None  # admitted: the key's row was read
    return principal, found


def active_version_of(
    subject: AnySubject, found: HotRow, principal: Principal, subject_id: str
) -> HotVersion:
    """The active version of a hot read's row, or the 404 that says why there is none: the
    subject unknown (or of a robot outside the key's cells), archived, or with no active
    version. The subject's own columns of the row are then set (never NULL)."""
    # The robot's cell came with the same statement: a key's cells cost no extra query.
    if found.subject_id is None or not principal.sees_cell(found.cell):
        raise NotFound(f"no {subject.kind} with id {subject_id}")
    if found.archived_at is not None:
        raise Archived(f"{subject.kind} {subject_id} ({found.subject_name}) was archived")
    if found.version is None:
        raise NoActiveVersion(
            f"{subject.kind} {subject_id} ({found.subject_name}) has no active "
            f"{subject.value} version yet"
        )
    # Columns of rows that exist (the subject's, and its active version's) are never NULL.
    assert found.position_mm is not None
    assert found.quaternion is not None
    assert found.source is not None
    assert found.created_at is not None
    assert found.created_by is not None
    return HotVersion(
        found.version,
        found.position_mm,
        found.quaternion,
        found.source,
        found.created_at,
        found.created_by,
    )


def served_etag(parts: list[object]) -> str:
    """Strong ETag of what is served of a subject's active version: a digest of every value
    the answer is made of (the subject's, the version's, the representation asked)."""
    payload = json.dumps(parts, sort_keys=True, default=str)
    return '"' + hashlib.sha256(payload.encode()).hexdigest()[:32] + '"'
