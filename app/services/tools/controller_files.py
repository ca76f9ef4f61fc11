"""Controller files: a tool's active TCP, or every tool of a robot, as the file its controller
loads (app.vendors), with the header saying which version, calibrated when and by whom.

A tool's file is served by the one-statement read of GET /v1/tools/{id}/tcp
(app.services.lifecycle.hot_read), which also reads who made the version.
"""

from __future__ import annotations

from typing import Protocol

from sqlalchemy import Engine, and_, select
from sqlalchemy.orm import Session

from app.config import get_settings
from app.errors import InvalidInput
from app.helpers.etags import if_none_match_hit
from app.security.auth import Principal
from app.services.lifecycle.hot_read import served_etag
from app.services.robots.robots import get_robot
from app.services.tools.controller_text import ServedTool, ServedVersion, tool_data
from app.services.tools.hot_read import active_of, read_for_key
from app.storage.models import TcpVersion, Tool
from app.vendors.files import ControllerFile, FileContext, FileTool, Provenance
from app.vendors.registry import controller_file
from app.words import FORMATS_IN_WORDS, ControllerFormat


def needs_format(fmt: ControllerFormat | None) -> ControllerFormat:
    """The format a file is asked in, or 422 naming ?format=."""
    if fmt is None:
        raise InvalidInput(
            "invalid-options",
            "Accept: text/plain serves a controller's file: give ?format= "
            f"({FORMATS_IN_WORDS}), or accept application/json",
            loc=("query", "format"),
        )
    return fmt


def public_url(request_base_url: str) -> str:
    """The server's URL for a file's header: TCPCAL_PUBLIC_URL, else the request's."""
    return (get_settings().public_url or request_base_url).rstrip("/")


class FileVersion(ServedVersion, Protocol):
    """What a file's header says of a version besides its values: who made it."""

    @property
    def created_by(self) -> str | None: ...


def file_tool(tool: ServedTool, version: FileVersion, *, base_url: str) -> FileTool:
    """A tool's active version as a file holds it, with its provenance (a models.Tool and
    TcpVersion, or the hot read's HotTool and HotVersion)."""
    origin = Provenance(
        version=version.version,
        calibrated_at=version.created_at,
        calibrated_by=version.created_by,
        method=version.source,
        url=f"{base_url}/ui/tools/{tool.id}",
    )
    return FileTool(tool_data(tool, version), origin)


def served_file_for_key(
    engine: Engine,
    *,
    authorization: str | None,
    tool_id: str,
    fmt: ControllerFormat | None,
    if_none_match: str | None,
    base_url: str,
) -> tuple[Principal, ControllerFile | None, str]:
    """(who, the tool's file or None when the client's copy is current, ETag): the key check,
    the tool and its active version in the JSON read's one statement
    (app.services.lifecycle.hot_read).
    A key limited to cells finds another cell's tool as absent as an unknown one."""
    principal, found = read_for_key(engine, authorization, tool_id)
    fmt = needs_format(fmt)
    tool, row = active_of(found, principal, tool_id)
    url = public_url(base_url)
    tool_part = [tool.id, tool.slot, tool.name, tool.load, tool.controller_symbol]
    version_part = [row.version, row.position_mm, row.quaternion, row.created_by]
    etag = served_etag([*tool_part, *version_part, fmt, "file", url])
    if if_none_match_hit(if_none_match, etag):
        return principal, None, etag
    item = file_tool(tool, row, base_url=url)
    return principal, controller_file(fmt, [item], FileContext(server_url=url)), etag


def robot_file(
    session: Session, *, robot_id: str, fmt: ControllerFormat | None, base_url: str
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
    items = [file_tool(tool, row, base_url=url) for tool, row in rows]
    uncalibrated = session.scalars(
        select(Tool.name)
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None), Tool.active_version.is_(None))
        .order_by(Tool.name)
    ).all()
    context = FileContext(
        robot=robot.name, server_url=url, table=True, without_version=tuple(uncalibrated)
    )
    return controller_file(fmt, items, context)
