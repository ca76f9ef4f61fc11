"""Controller files: a tool's active TCP, or every tool of a robot, as the file its controller
loads (app.exports), with the header saying which version, calibrated when and by whom.

The JSON read of GET /v1/tools/{id}/tcp (app.services.versions) is untouched: the file is
served by its own one-statement read, which also reads who made the version.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from datetime import datetime

import numpy as np
from sqlalchemy import Engine, and_, bindparam, select
from sqlalchemy.orm import Session

from app.auth import Principal, admit, digest_of
from app.config import get_settings
from app.db import HeldRead
from app.errors import Archived, InvalidInput, NoActiveVersion, NotFound
from app.exports import (
    ControllerFile,
    FileContext,
    FileTool,
    Provenance,
    ToolData,
    controller_file,
)
from app.helpers.etags import if_none_match_hit
from app.jsontypes import JsonObject
from app.models import ApiKey, Robot, TcpVersion, Tool, table_of
from app.services.robots import get_robot

_KEY = ApiKey.__table__
_TOOL = table_of(Tool)
_VERSION = table_of(TcpVersion)
_ROBOT = table_of(Robot)
_FILE_READ = HeldRead(
    select(
        _KEY.c.id,
        _KEY.c.name,
        _KEY.c.scope,
        _KEY.c.key_hash,
        _KEY.c.revoked_at,
        _KEY.c.cells,
        _ROBOT.c.cell,
        _TOOL.c.id.label("tool_id"),
        _TOOL.c.name.label("tool_name"),
        _TOOL.c.slot,
        _TOOL.c.load,
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
    .where(_KEY.c.key_hash == bindparam("digest"))
)


def needs_format(fmt: str | None) -> str:
    """The format a file is asked in, or 422 naming ?format=."""
    if fmt is None:
        raise InvalidInput(
            "invalid-options",
            "Accept: text/plain serves a controller's file: give ?format= (kuka, abb, fanuc, "
            "ur, yaskawa or techman), or accept application/json",
            loc=("query", "format"),
        )
    return fmt


def public_url(request_base_url: str) -> str:
    """The server's URL for a file's header: TCPCAL_PUBLIC_URL, else the request's."""
    return (get_settings().public_url or request_base_url).rstrip("/")


def file_tool(
    *,
    tool_id: str,
    name: str,
    slot: int | None,
    load: JsonObject | None,
    version: int,
    position_mm: Sequence[float],
    quaternion: Sequence[float],
    method: str,
    created_at: datetime,
    created_by: str | None,
    base_url: str,
) -> FileTool:
    """A tool's active version as a file holds it, with its provenance."""
    load = load or {}
    cog = load.get("cog_mm")
    mass = load.get("mass_kg")
    data = ToolData(
        slot=slot,
        name=name,
        position_mm=np.asarray(position_mm, dtype=float),
        quaternion_wxyz=np.asarray(quaternion, dtype=float),
        mass_kg=float(mass) if isinstance(mass, int | float) else None,
        cog_mm=np.asarray(cog, dtype=float) if isinstance(cog, list) else None,
    )
    origin = Provenance(
        version=version,
        calibrated_at=created_at,
        calibrated_by=created_by,
        method=method,
        url=f"{base_url}/ui/tools/{tool_id}",
    )
    return FileTool(data, origin)


def _etag(parts: list[object]) -> str:
    payload = json.dumps(parts, sort_keys=True, default=str)
    return '"' + hashlib.sha256(payload.encode()).hexdigest()[:32] + '"'


def served_file_for_key(
    engine: Engine,
    *,
    authorization: str | None,
    tool_id: str,
    fmt: str | None,
    if_none_match: str | None,
    base_url: str,
) -> tuple[Principal, ControllerFile | None, str]:
    """(who, the tool's file or None when the client's copy is current, ETag): the key check,
    the tool and its active version in one statement, as the JSON read does."""
    digest = digest_of(authorization)
    found = _FILE_READ.one_or_none(engine, digest=digest, tool_id=tool_id)
    principal = admit(found, digest, required="read")
    assert found is not None
    fmt = needs_format(fmt)
    # A key limited to cells: another cell's tool is as absent as an unknown one.
    if found.tool_id is None or not principal.sees_cell(found.cell):
        raise NotFound(f"no tool with id {tool_id}")
    if found.archived_at is not None:
        raise Archived(f"tool {tool_id} ({found.tool_name}) was archived")
    if found.version is None:
        raise NoActiveVersion(f"tool {tool_id} ({found.tool_name}) has no active TCP version yet")
    url = public_url(base_url)
    tool_part = [found.tool_id, found.slot, found.tool_name, found.load]
    version_part = [found.version, found.position_mm, found.quaternion, found.created_by]
    etag = _etag([*tool_part, *version_part, fmt, "file", url])
    if if_none_match_hit(if_none_match, etag):
        return principal, None, etag
    item = file_tool(
        tool_id=found.tool_id,
        name=found.tool_name,
        slot=found.slot,
        load=found.load,
        version=found.version,
        position_mm=found.position_mm,
        quaternion=found.quaternion,
        method=found.source,
        created_at=found.created_at,
        created_by=found.created_by,
        base_url=url,
    )
    return principal, controller_file(fmt, [item], FileContext(server_url=url)), etag


def robot_file(
    session: Session, *, robot_id: str, fmt: str | None, base_url: str
) -> ControllerFile:
    """Every live tool of a robot with an active version, in one file of format `fmt`; tools
    the format cannot hold are named in its header."""
    fmt = needs_format(fmt)
    robot = get_robot(session, robot_id)
    rows = session.execute(
        select(Tool, TcpVersion)
        .join(
            TcpVersion,
            and_(TcpVersion.tool_id == Tool.id, TcpVersion.version == Tool.active_version),
        )
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
        .order_by(Tool.slot, Tool.name)
    ).all()
    url = public_url(base_url)
    items = [
        file_tool(
            tool_id=tool.id,
            name=tool.name,
            slot=tool.slot,
            load=tool.load,
            version=row.version,
            position_mm=row.position_mm,
            quaternion=row.quaternion,
            method=row.source,
            created_at=row.created_at,
            created_by=row.created_by,
            base_url=url,
        )
        for tool, row in rows
    ]
    uncalibrated = session.scalars(
        select(Tool.name)
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None), Tool.active_version.is_(None))
        .order_by(Tool.name)
    ).all()
    context = FileContext(
        robot=robot.name, server_url=url, table=True, without_version=tuple(uncalibrated)
    )
    return controller_file(fmt, items, context)
