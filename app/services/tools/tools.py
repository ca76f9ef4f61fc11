"""Tools of a robot: register, list, update, archive; the tool's ETag and If-Match."""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import InvalidInput
from app.helpers.pagination import paginate
from app.helpers.tolerance import effective_tolerance
from app.schemas.tools import Load, ToolCreate, ToolUpdate
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.lifecycle.versions import (
    Patch,
    Revised,
    Taken,
    apply_update,
    check_unique,
    etag,
    patched,
)
from app.services.lifecycle.versions import check_if_match as lifecycle_check_if_match
from app.services.robots.connection import check_slot_for_controller
from app.services.robots.robots import get_robot
from app.services.robots.slots import check_slot
from app.services.tools.subject import TOOL
from app.services.visible import get_live, visible_tool
from app.storage.models import Tool, new_id, utcnow


def get_tool(session: Session, tool_id: str, *, for_update: bool = False) -> Tool:
    """A live tool, or 404. `for_update` locks the row (serialises versions)."""
    return get_live(session, Tool, tool_id, for_update=for_update)


def tool_named_in_body(
    session: Session, tool_id: str, *, robot_id: str, loc: tuple[str, ...]
) -> Tool:
    """A live tool of the robot that a request body names (a reference tool, a teaching
    tool): when there is none, the body field is wrong (422 at `loc`), not the URL (404)."""
    tool = visible_tool(session, tool_id)
    if tool is None or tool.archived_at is not None or tool.robot_id != robot_id:
        raise InvalidInput(
            "unknown-reference",
            f"robot {robot_id} has no tool {tool_id} in service; name one of its live tools",
            loc=loc,
        )
    return tool


def tool_etag(tool: Revised) -> str:
    """Strong ETag of a tool; changes with every change to it, its versions or activation."""
    return etag(tool)


def check_if_match(tool: Revised, if_match: str | None) -> None:
    """412 when an If-Match header does not name the tool's current ETag."""
    lifecycle_check_if_match(TOOL, tool, if_match)


#: A taken name or slot, in the tool's words (check_unique).
_TAKEN = Taken(
    name="robot {robot_id} already has a tool named {name!r}",
    slot="slot {slot} of robot {robot_id} is already taken by another tool",
)


def create_tool(session: Session, *, robot_id: str, data: ToolCreate, actor: Principal) -> Tool:
    """Register a tool on a robot (name and slot unique among the robot's live tools)."""
    robot = get_robot(session, robot_id, for_update=True)
    check_slot(robot.vendor, data.slot, loc=("body", "slot"))
    check_unique(session, TOOL, _TAKEN, robot_id, {"name": data.name, "slot": data.slot})
    check_slot_for_controller(session, robot_id=robot_id, slot=data.slot)
    values = data.model_dump()
    tool = Tool(id=new_id(), robot_id=robot_id, last_version=0, revision=1, **values)
    return audit.add_created(
        session,
        tool,
        actor=actor,
        action="tool.create",
        resource_type="tool",
        robot_id=robot_id,
        tool_id=tool.id,
        details={"name": tool.name, "slot": tool.slot, "tolerance": tool.tolerance},
    )


def list_tools(
    session: Session, *, robot_id: str, limit: int, cursor: str | None
) -> tuple[Sequence[Tool], str | None]:
    """Live tools of a robot."""
    get_robot(session, robot_id)  # 404 for a robot of another cell: its tools are not listed
    stmt = select(Tool).where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
    return paginate(
        session, stmt, created_col=Tool.created_at, id_col=Tool.id, limit=limit, cursor=cursor
    )


#: What a tool's PATCH writes: its event shows the old and new values of all its fields
#: but the free text.
_PATCH = Patch(
    action="tool.update",
    shown=("name", "slot", "serial", "load", "tolerance", "controller_symbol"),
    tolerance=effective_tolerance,
)


def update_tool(
    session: Session, *, tool_id: str, data: ToolUpdate, if_match: str | None, actor: Principal
) -> Tool:
    """Change the fields given in the PATCH body (If-Match honoured)."""
    tool = get_tool(session, tool_id, for_update=True)
    check_if_match(tool, if_match)
    changes = patched(data)
    if changes.get("slot") is not None:
        check_slot(get_robot(session, tool.robot_id).vendor, changes["slot"], loc=("body", "slot"))
    check_unique(session, TOOL, _TAKEN, tool.robot_id, changes, except_id=tool.id)
    check_slot_for_controller(session, robot_id=tool.robot_id, slot=changes.get("slot"))
    if changes.get("load") is not None and tool.load is not None:  # merges as the tolerance
        changes["load"] = Load.model_validate({**tool.load, **changes["load"]}).model_dump()
    apply_update(session, TOOL, _PATCH, tool, changes, actor=actor)
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
