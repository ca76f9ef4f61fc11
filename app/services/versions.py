"""TCP versions: numbering, activation (with history), and serving the active TCP."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.auth import Principal
from app.errors import NoActiveVersion, NotFound
from app.models import Activation, TcpVersion, Tool, utcnow
from app.services import audit
from app.services.registry import check_if_match, get_robot, get_tool

IDENTITY_QUATERNION = [1.0, 0.0, 0.0, 0.0]


def add_version(
    session: Session,
    *,
    tool: Tool,
    position_mm: Sequence[float],
    quaternion: Sequence[float],
    source: str,
    status: str,
    calibration_id: str | None,
    note: str | None,
    actor: Principal,
) -> TcpVersion:
    """Append version n+1 of a tool. The caller holds the tool row lock (get_tool(for_update))."""
    tool.last_version += 1
    tool.revision += 1
    tool.updated_at = utcnow()
    row = TcpVersion(
        tool_id=tool.id,
        version=tool.last_version,
        position_mm=[float(v) for v in position_mm],
        quaternion=[float(v) for v in quaternion],
        source=source,
        status=status,
        calibration_id=calibration_id,
        note=note,
        created_by=actor.name,
    )
    session.add(row)
    session.flush()
    audit.record(
        session,
        actor=actor,
        action="version.create",
        resource_type="tool",
        resource_id=tool.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        details={"version": row.version, "source": source, "status": status},
    )
    return row


def activate(
    session: Session, *, tool: Tool, version: int, reason: str, actor: Principal
) -> Activation:
    """Make `version` the active one and record who did it and when (lock held by caller)."""
    row = Activation(
        tool_id=tool.id,
        version=version,
        previous_version=tool.active_version,
        reason=reason,
        activated_by=actor.name,
        activated_at=utcnow(),
    )
    tool.active_version = version
    tool.revision += 1
    tool.updated_at = utcnow()
    session.add(row)
    session.flush()
    audit.record(
        session,
        actor=actor,
        action="version.activate",
        resource_type="tool",
        resource_id=tool.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        details={"version": version, "previous_version": row.previous_version, "reason": reason},
    )
    return row


def get_version(session: Session, *, tool_id: str, version: int) -> TcpVersion:
    """One version of a live tool, or 404."""
    get_tool(session, tool_id)
    row = session.scalars(
        select(TcpVersion).where(TcpVersion.tool_id == tool_id, TcpVersion.version == version)
    ).one_or_none()
    if row is None:
        raise NotFound(f"tool {tool_id} has no version {version}")
    return row


def list_versions(
    session: Session, *, tool_id: str
) -> tuple[Tool, list[TcpVersion], list[Activation]]:
    """Every version of a tool (oldest first) and its activation history."""
    tool = get_tool(session, tool_id)
    versions = list(
        session.scalars(
            select(TcpVersion).where(TcpVersion.tool_id == tool_id).order_by(TcpVersion.version)
        )
    )
    history = list(
        session.scalars(
            select(Activation).where(Activation.tool_id == tool_id).order_by(Activation.id)
        )
    )
    return tool, versions, history


def activate_version(
    session: Session, *, tool_id: str, version: int, if_match: str | None, actor: Principal
) -> Tool:
    """Activate an existing version (roll forward or back), honouring If-Match."""
    tool = get_tool(session, tool_id, for_update=True)
    check_if_match(tool, if_match)
    get_version(session, tool_id=tool_id, version=version)
    activate(session, tool=tool, version=version, reason="explicit", actor=actor)
    return tool


def active_version_row(session: Session, tool: Tool) -> TcpVersion:
    """The active version of a tool, or 404 /no-active-version."""
    if tool.active_version is None:
        raise NoActiveVersion(f"tool {tool.id} ({tool.name}) has no active TCP version yet")
    return session.scalars(
        select(TcpVersion).where(
            TcpVersion.tool_id == tool.id, TcpVersion.version == tool.active_version
        )
    ).one()


def tcp_etag(tool: Tool, row: TcpVersion) -> str:
    """Strong ETag of what /tcp serves: changes when the served numbers or slot change."""
    payload = json.dumps(
        [tool.id, tool.slot, tool.name, tool.load, row.version, row.position_mm, row.quaternion],
        sort_keys=True,
    )
    return '"' + hashlib.sha256(payload.encode()).hexdigest()[:32] + '"'


def active_tcp(session: Session, *, tool_id: str) -> tuple[Tool, TcpVersion]:
    """The tool and its active version (404 when archived or none)."""
    tool = get_tool(session, tool_id)
    return tool, active_version_row(session, tool)


def tool_table(
    session: Session, *, robot_id: str
) -> tuple[list[tuple[Tool, TcpVersion]], list[str]]:
    """Every live tool of a robot with its active version; ids of those without one."""
    get_robot(session, robot_id)
    tools = session.scalars(
        select(Tool)
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
        .order_by(Tool.slot, Tool.name)
    ).all()
    served: list[tuple[Tool, TcpVersion]] = []
    missing: list[str] = []
    for tool in tools:
        if tool.active_version is None:
            missing.append(tool.id)
        else:
            served.append((tool, active_version_row(session, tool)))
    return served, missing
