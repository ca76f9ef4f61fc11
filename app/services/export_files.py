"""Controller files: a tool's active TCP, or every tool of a robot, as the file its controller
loads (app.exports), with the header saying which version, calibrated when and by whom.

A tool's file is served by the one-statement read of GET /v1/tools/{id}/tcp
(app.services.hot_read), which also reads who made the version.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from datetime import datetime

import numpy as np
from sqlalchemy import Engine, and_, select
from sqlalchemy.orm import Session

from app.auth import Principal
from app.config import get_settings
from app.errors import InvalidInput
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
from app.models import TcpVersion, Tool
from app.services.hot_read import active_of, read_for_key
from app.services.robots import get_robot


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
    the tool and its active version in the JSON read's one statement (app.services.hot_read).
    A key limited to cells finds another cell's tool as absent as an unknown one."""
    principal, found = read_for_key(engine, authorization, tool_id)
    fmt = needs_format(fmt)
    tool, row = active_of(found, principal, tool_id)
    url = public_url(base_url)
    tool_part = [tool.id, tool.slot, tool.name, tool.load]
    version_part = [row.version, row.position_mm, row.quaternion, row.created_by]
    etag = _etag([*tool_part, *version_part, fmt, "file", url])
    if if_none_match_hit(if_none_match, etag):
        return principal, None, etag
    item = file_tool(
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
