"""TCP versions: the tool's bindings of the lifecycle's numbering and activation
(app.services.lifecycle.versions), and serving the active TCP."""

from __future__ import annotations

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from app.config import get_settings
from app.errors import InvalidInput
from app.helpers.etags import if_none_match_hit
from app.schemas.tools import ActiveTcp, Tcp, ToolTable, Version
from app.security.auth import Principal
from app.services.lifecycle import versions as lifecycle
from app.services.lifecycle.hot_read import served_etag
from app.services.lifecycle.subject import Locked
from app.services.robots.robots import get_robot
from app.services.tools.controller_text import ServedTool, ServedVersion, controller_text
from app.services.tools.hot_read import active_of, read_for_key
from app.services.tools.subject import TOOL
from app.services.tools.tools import get_tool
from app.storage.models import Activation, TcpVersion, Tool
from app.words import (
    FORMATS_IN_WORDS,
    ControllerFormat,
)

IDENTITY_QUATERNION = [1.0, 0.0, 0.0, 0.0]


# ---- the writes: numbering and activation under the tool's lock (app.services.lifecycle) ------
#: A tool read under its row lock (app.services.lifecycle.versions.Locked).
LockedTool = Locked


def lock_tool(session: Session, tool_id: str) -> LockedTool:
    """Lock a live tool's row for the rest of the transaction (serialises its versions), or
    404."""
    return lifecycle.lock(session, TOOL, tool_id)


def save_deferred(session: Session, tool: LockedTool) -> None:
    """Write what deferred writes changed: the tool's counters and its drift trend. (A tool's
    versions are added and activated by app.services.lifecycle.versions with TOOL.)"""
    lifecycle.save_deferred(session, TOOL, tool)


def get_version(session: Session, *, tool_id: str, version: int) -> TcpVersion:
    """One version of a live tool, or 404."""
    return lifecycle.get_version(session, TOOL, subject_id=tool_id, version=version)


def list_versions(
    session: Session, *, tool_id: str
) -> tuple[Tool, list[TcpVersion], list[Activation]]:
    """Every version of a tool (oldest first) and its activation history."""
    return lifecycle.list_versions(session, TOOL, subject_id=tool_id)


def active_version_row(session: Session, tool: Tool) -> TcpVersion:
    """The active version of a tool, or 404 /no-active-version."""
    return lifecycle.active_version_row(session, TOOL, tool)


def tcp_etag(
    tool: ServedTool, row: ServedVersion, fmt: ControllerFormat | None, as_text: bool = False
) -> str:
    """Strong ETag of what /tcp serves: the numbers, slot, load and the representation
    (the JSON document or the controller text alone)."""
    return served_etag(
        [
            tool.id,
            tool.slot,
            tool.name,
            tool.load,
            row.version,
            row.position_mm,
            row.quaternion,
            fmt,
            as_text,
        ]
    )


def version_document(row: TcpVersion, tool: Tool) -> Version:
    """A version as the API shows it."""
    return Version(
        version=row.version,
        tcp=Tcp(position_mm=row.position_mm, quaternion=row.quaternion),
        source=row.source,
        status=row.status,
        calibration_id=row.calibration_id,
        note=row.note,
        created_at=row.created_at,
        created_by=row.created_by,
        active=tool.active_version == row.version,
    )


def active_document(
    tool: ServedTool, row: ServedVersion, fmt: ControllerFormat | None
) -> ActiveTcp:
    """What a cell controller reads: the active TCP, and its controller text when asked."""
    return ActiveTcp(
        tool_id=tool.id,
        robot_id=tool.robot_id,
        tool_name=tool.name,
        slot=tool.slot,
        version=row.version,
        tcp=Tcp(position_mm=row.position_mm, quaternion=row.quaternion),
        calibrated_at=row.created_at,
        method=row.source,
        controller=None if fmt is None else controller_text(fmt, tool=tool, version=row),
    )


def _text_needs_format(as_text: bool, fmt: ControllerFormat | None) -> None:
    if as_text and fmt is None:
        raise InvalidInput(
            "invalid-options",
            "Accept: text/plain serves a controller's text: give ?format= "
            f"({FORMATS_IN_WORDS}), or accept application/json",
            loc=("query", "format"),
        )


def served_tcp(
    session: Session,
    *,
    tool_id: str,
    fmt: ControllerFormat | None,
    if_none_match: str | None,
    as_text: bool = False,
) -> tuple[ActiveTcp | None, str]:
    """(document, ETag) of a tool's active TCP; document None when the client's copy is current.
    `as_text`: the controller text alone will be served (its own ETag)."""
    _text_needs_format(as_text, fmt)
    tool = get_tool(session, tool_id)
    row = active_version_row(session, tool)
    etag = tcp_etag(tool, row, fmt, as_text)
    if if_none_match_hit(if_none_match, etag):
        return None, etag
    return active_document(tool, row, fmt), etag


def tool_table(session: Session, *, robot_id: str, fmt: ControllerFormat | None) -> ToolTable:
    """Every live tool's active TCP. A tool the format cannot express (no slot where it
    numbers tools, no load where it holds one) carries its own controller_error instead of
    failing the whole table."""
    get_robot(session, robot_id)
    tools = session.scalars(
        select(Tool)
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
        .order_by(Tool.slot, Tool.name)
    ).all()
    items: list[ActiveTcp] = []
    missing: list[str] = []
    for tool in tools:
        if tool.active_version is None:
            missing.append(tool.id)
            continue
        row = active_version_row(session, tool)
        try:
            items.append(active_document(tool, row, fmt))
        except InvalidInput as exc:
            item = active_document(tool, row, None)
            item.controller_error = {
                "type": get_settings().problem_type(exc.kind),
                "detail": exc.detail,
            }
            items.append(item)
    return ToolTable(robot_id=robot_id, items=items, without_active_version=missing)


def served_tcp_for_key(
    engine: Engine,
    *,
    authorization: str | None,
    tool_id: str,
    fmt: ControllerFormat | None,
    if_none_match: str | None,
    as_text: bool = False,
) -> tuple[Principal, ActiveTcp | None, str]:
    """`served_tcp` for the caller behind `authorization`: the key check, the tool and its
    active version in one statement (app.services.tools.hot_read): (who, document or None when the
    client's copy is current, ETag)."""
    principal, found = read_for_key(engine, authorization, tool_id)
    _text_needs_format(as_text, fmt)
    tool, row = active_of(found, principal, tool_id)
    etag = tcp_etag(tool, row, fmt, as_text)
    if if_none_match_hit(if_none_match, etag):
        return principal, None, etag
    return principal, active_document(tool, row, fmt), etag
