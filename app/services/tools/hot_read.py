"""The hot read: the caller's key, a tool and its active version in one statement.

What a fleet of cell controllers polls, as JSON (GET /v1/tools/{id}/tcp,
app.services.tools.versions) or as its controller's file (app.services.tools.controller_files): one
statement on the thread's held connection (app.storage.db.HeldRead), no ORM, no transaction around
it, nothing cached, so a revoked key or a new activation is seen by the very next request.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple

from sqlalchemy import Engine, and_, bindparam, select

from app.errors import Archived, NoActiveVersion, NotFound
from app.jsontypes import JsonArray, JsonObject
from app.scopes import Scope
from app.security.auth import Principal, admit, digest_of
from app.storage.db import HeldRead
from app.storage.models import ApiKey, Robot, TcpVersion, Tool, table_of
from app.words import MethodName


class HotRow(NamedTuple):
    """A row of HOT_READ: the key under its own column names (what `admit` reads), then the
    tool, its robot's cell and its active version, each None when the tool is unknown or has
    no active version (outer joins)."""

    id: str
    name: str
    scope: Scope
    key_hash: str
    revoked_at: datetime | None
    cells: JsonArray | None
    cell: str | None
    tool_id: str | None
    robot_id: str | None
    tool_name: str | None
    slot: int | None
    load: JsonObject | None
    controller_symbol: str | None
    archived_at: datetime | None
    version: int | None
    position_mm: JsonArray | None
    quaternion: JsonArray | None
    source: MethodName | None
    created_at: datetime | None
    created_by: str | None


_KEY, _ROBOT = table_of(ApiKey), table_of(Robot)
_TOOL, _VERSION = table_of(Tool), table_of(TcpVersion)
HOT_READ = HeldRead(
    HotRow,
    select(
        _KEY.c.id,
        _KEY.c.name,
        _KEY.c.scope,
        _KEY.c.key_hash,
        _KEY.c.revoked_at,
        _KEY.c.cells,
        _ROBOT.c.cell,
        _TOOL.c.id.label("tool_id"),
        _TOOL.c.robot_id,
        _TOOL.c.name.label("tool_name"),
        _TOOL.c.slot,
        _TOOL.c.load,
        _TOOL.c.controller_symbol,
        _TOOL.c.archived_at,
        _VERSION.c.version,
        _VERSION.c.position_mm,
        _VERSION.c.quaternion,
        _VERSION.c.source,
        _VERSION.c.created_at,
        _VERSION.c.created_by,
    )
    .select_from(_KEY)
    .outerjoin(_TOOL, _TOOL.c.id == bindparam("tool_id"))
    .outerjoin(_ROBOT, _ROBOT.c.id == _TOOL.c.robot_id)
    .outerjoin(
        _VERSION,
        and_(_VERSION.c.tool_id == _TOOL.c.id, _VERSION.c.version == _TOOL.c.active_version),
    )
    .where(_KEY.c.key_hash == bindparam("digest")),
)


# Plain records, not ORM objects: an instrumented __init__ cost 50 us a request here.
@dataclass(frozen=True, slots=True)
class HotTool:
    """The tool of a hot read (an app.services.tools.controller_text.ServedTool)."""

    id: str
    robot_id: str
    name: str
    slot: int | None
    load: JsonObject | None
    controller_symbol: str | None


@dataclass(frozen=True, slots=True)
class HotVersion:
    """The active version of a hot read (an app.services.tools.controller_text.ServedVersion), and
    who made it."""

    version: int
    position_mm: JsonArray
    quaternion: JsonArray
    source: MethodName
    created_at: datetime
    created_by: str


def read_for_key(
    engine: Engine, authorization: str | None, tool_id: str
) -> tuple[Principal, HotRow]:
    """(who, the row) for the caller behind `authorization` and a tool: 401 for no key or
    an unknown or revoked one, 403 for too small a scope (a key comes before the tool)."""
    digest = digest_of(authorization)
    found = HOT_READ.one_or_none(engine, digest=digest, tool_id=tool_id)
    principal = admit(found, digest, required="read")
    assert found is not None  # admitted: the key's row was read
    return principal, found


def active_of(found: HotRow, principal: Principal, tool_id: str) -> tuple[HotTool, HotVersion]:
    """The tool and its active version of a hot read's row, or the 404 that says why not:
    unknown (or of a robot outside the key's cells), archived, or no active version."""
    # The robot's cell came with the same statement: a key's cells cost no extra query.
    if found.tool_id is None or not principal.sees_cell(found.cell):
        raise NotFound(f"no tool with id {tool_id}")
    if found.archived_at is not None:
        raise Archived(f"tool {tool_id} ({found.tool_name}) was archived")
    if found.version is None:
        raise NoActiveVersion(f"tool {tool_id} ({found.tool_name}) has no active TCP version yet")
    # Columns of rows that exist (the tool's, and its active version's) are never NULL.
    assert found.robot_id is not None
    assert found.tool_name is not None
    assert found.position_mm is not None
    assert found.quaternion is not None
    assert found.source is not None
    assert found.created_at is not None
    assert found.created_by is not None
    tool = HotTool(
        found.tool_id,
        found.robot_id,
        found.tool_name,
        found.slot,
        found.load,
        found.controller_symbol,
    )
    version = HotVersion(
        found.version,
        found.position_mm,
        found.quaternion,
        found.source,
        found.created_at,
        found.created_by,
    )
    return tool, version
