"""Robots and tools: the fleet registry (create, read, update, archive)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import Any, TypeVar

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.auth import Principal
from app.errors import Archived, Conflict, NotFound, PreconditionFailed
from app.models import Robot, Tool, utcnow
from app.schemas.robots import RobotCreate, RobotUpdate
from app.schemas.tools import Load, ToolCreate, ToolUpdate
from app.services import audit
from app.services.etags import if_match_ok
from app.services.kinematics import validate_kinematics
from app.services.pagination import paginate
from app.services.tolerance import effective_tolerance

# ---- robots ---------------------------------------------------------------------------------
Live = TypeVar("Live", Robot, Tool)


def _get_live(session: Session, model: type[Live], row_id: str, *, for_update: bool) -> Live:
    """A row that is not archived, or 404 (/not-found, or /archived when it was deleted)."""
    what = model.__name__.lower()
    stmt = select(model).where(model.id == row_id)
    if for_update:
        stmt = stmt.with_for_update()
    row = session.scalars(stmt).one_or_none()
    if row is None:
        raise NotFound(f"no {what} with id {row_id}")
    if row.archived_at is not None:
        raise Archived(f"{what} {row_id} ({row.name}) was archived")
    return row


def get_robot(session: Session, robot_id: str, *, for_update: bool = False) -> Robot:
    """A live robot, or 404."""
    return _get_live(session, Robot, robot_id, for_update=for_update)


def _robot_name_free(session: Session, name: str, *, except_id: str | None = None) -> None:
    stmt = select(Robot.id).where(Robot.name == name, Robot.archived_at.is_(None))
    if except_id:
        stmt = stmt.where(Robot.id != except_id)
    if session.scalars(stmt).first():
        raise Conflict(
            f"a robot named {name!r} already exists",
            errors=[{"loc": ["body", "name"], "msg": "already taken"}],
        )


def create_robot(session: Session, *, data: RobotCreate, actor: Principal) -> Robot:
    """Register a robot (name unique among live robots)."""
    _robot_name_free(session, data.name)
    values = data.model_dump()
    values["kinematics"] = validate_kinematics(data.kinematics)
    robot = Robot(**values)
    session.add(robot)
    session.flush()
    audit.record(
        session,
        actor=actor,
        action="robot.create",
        resource_type="robot",
        resource_id=robot.id,
        robot_id=robot.id,
        details={"name": robot.name},
    )
    return robot


def list_robots(
    session: Session, *, cell: str | None, name: str | None, limit: int, cursor: str | None
) -> tuple[Sequence[Robot], str | None]:
    """Live robots, optionally filtered by cell or exact name."""
    stmt = select(Robot).where(Robot.archived_at.is_(None))
    if cell is not None:
        stmt = stmt.where(Robot.cell == cell)
    if name is not None:
        stmt = stmt.where(Robot.name == name)
    return paginate(
        session, stmt, created_col=Robot.created_at, id_col=Robot.id, limit=limit, cursor=cursor
    )


def update_robot(session: Session, *, robot_id: str, data: RobotUpdate, actor: Principal) -> Robot:
    """Change the fields given in the PATCH body."""
    robot = get_robot(session, robot_id, for_update=True)
    changes = data.model_dump(exclude_unset=True)
    if changes.get("name") is None:
        changes.pop("name", None)
    if "name" in changes:
        _robot_name_free(session, changes["name"], except_id=robot.id)
    if "kinematics" in changes:
        changes["kinematics"] = validate_kinematics(data.kinematics)
    for key, value in changes.items():
        setattr(robot, key, value)
    robot.updated_at = utcnow()
    audit.record(
        session,
        actor=actor,
        action="robot.update",
        resource_type="robot",
        resource_id=robot.id,
        robot_id=robot.id,
        details={"changed": sorted(changes)},
    )
    return robot


def archive_robot(session: Session, *, robot_id: str, actor: Principal) -> None:
    """Archive a robot and its tools; their history stays."""
    robot = get_robot(session, robot_id, for_update=True)
    now = utcnow()
    robot.archived_at = now
    tools = session.scalars(
        select(Tool).where(Tool.robot_id == robot.id, Tool.archived_at.is_(None))
    ).all()
    for tool in tools:
        tool.archived_at = now
        tool.revision += 1
    audit.record(
        session,
        actor=actor,
        action="robot.archive",
        resource_type="robot",
        resource_id=robot.id,
        robot_id=robot.id,
        details={"archived_tools": [t.id for t in tools]},
    )


# ---- tools ----------------------------------------------------------------------------------
def get_tool(session: Session, tool_id: str, *, for_update: bool = False) -> Tool:
    """A live tool, or 404. `for_update` locks the row (serialises versions)."""
    return _get_live(session, Tool, tool_id, for_update=for_update)


def tool_etag(tool: Tool) -> str:
    """Strong ETag of a tool; changes with every change to it, its versions or activation."""
    digest = hashlib.sha256(f"{tool.id}:{tool.revision}".encode()).hexdigest()[:20]
    return f'"{digest}"'


def check_if_match(tool: Tool, if_match: str | None) -> None:
    """412 when an If-Match header does not name the tool's current ETag."""
    if if_match_ok(if_match, tool_etag(tool)):
        return
    raise PreconditionFailed(
        f"tool {tool.id} changed since you read it: its ETag is now {tool_etag(tool)}; "
        "read it again and retry",
        headers={"ETag": tool_etag(tool)},
    )


def _tool_unique(
    session: Session,
    *,
    robot_id: str,
    name: str | None,
    slot: int | None,
    except_id: str | None = None,
) -> None:
    live = select(Tool.id).where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
    if except_id:
        live = live.where(Tool.id != except_id)
    if name is not None and session.scalars(live.where(Tool.name == name)).first():
        raise Conflict(
            f"robot {robot_id} already has a tool named {name!r}",
            errors=[{"loc": ["body", "name"], "msg": "already taken"}],
        )
    if slot is not None and session.scalars(live.where(Tool.slot == slot)).first():
        raise Conflict(
            f"slot {slot} of robot {robot_id} is already taken by another tool",
            errors=[{"loc": ["body", "slot"], "msg": "already taken"}],
        )


def create_tool(session: Session, *, robot_id: str, data: ToolCreate, actor: Principal) -> Tool:
    """Register a tool on a robot (name and slot unique among the robot's live tools)."""
    get_robot(session, robot_id, for_update=True)
    _tool_unique(session, robot_id=robot_id, name=data.name, slot=data.slot)
    values: dict[str, Any] = data.model_dump()
    tool = Tool(robot_id=robot_id, last_version=0, revision=1, **values)
    session.add(tool)
    session.flush()
    audit.record(
        session,
        actor=actor,
        action="tool.create",
        resource_type="tool",
        resource_id=tool.id,
        robot_id=robot_id,
        tool_id=tool.id,
        details={"name": tool.name, "slot": tool.slot},
    )
    return tool


def list_tools(
    session: Session, *, robot_id: str, limit: int, cursor: str | None
) -> tuple[Sequence[Tool], str | None]:
    """Live tools of a robot."""
    get_robot(session, robot_id)
    stmt = select(Tool).where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
    return paginate(
        session, stmt, created_col=Tool.created_at, id_col=Tool.id, limit=limit, cursor=cursor
    )


def update_tool(
    session: Session, *, tool_id: str, data: ToolUpdate, if_match: str | None, actor: Principal
) -> Tool:
    """Change the fields given in the PATCH body (If-Match honoured)."""
    tool = get_tool(session, tool_id, for_update=True)
    check_if_match(tool, if_match)
    changes = data.model_dump(exclude_unset=True)
    if changes.get("name", "") is None:
        changes.pop("name")
    _tool_unique(
        session,
        robot_id=tool.robot_id,
        name=changes.get("name"),
        slot=changes.get("slot"),
        except_id=tool.id,
    )
    # Nested objects merge (JSON merge patch): {"tolerance": {"max_rms_mm": 0.2}} changes that
    # one limit and keeps the others, rather than resetting them to the defaults.
    if "tolerance" in changes:
        if changes["tolerance"] is None:
            changes.pop("tolerance")
        else:
            changes["tolerance"] = {**effective_tolerance(tool.tolerance), **changes["tolerance"]}
    if changes.get("load") is not None and tool.load is not None:
        changes["load"] = Load.model_validate({**tool.load, **changes["load"]}).model_dump()
    for key, value in changes.items():
        setattr(tool, key, value)
    tool.updated_at = utcnow()
    tool.revision += 1
    audit.record(
        session,
        actor=actor,
        action="tool.update",
        resource_type="tool",
        resource_id=tool.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        details={"changed": sorted(changes)},
    )
    return tool


def archive_tool(session: Session, *, tool_id: str, actor: Principal) -> None:
    """Archive a tool: it stops serving a TCP; its history stays."""
    tool = get_tool(session, tool_id, for_update=True)
    tool.archived_at = utcnow()
    tool.revision += 1
    audit.record(
        session,
        actor=actor,
        action="tool.archive",
        resource_type="tool",
        resource_id=tool.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
    )
