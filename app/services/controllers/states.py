"""Each tool's controller state (in sync, drifted, unreachable, no active version, not live)
as the last reconcile or deployment saw it; a change of state is an audit event, once."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.jsontypes import JsonObject
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.storage.models import Tool, ToolControllerState
from app.vendors.tool import ToolData
from app.words import AuditAction, ToolState

#: States whose start is an audit event `controller.<state>` (and counted in /metrics), with
#: that event's action.
EVENT_ACTIONS: dict[ToolState, AuditAction] = {
    "in_sync": "controller.in_sync",
    "drifted": "controller.drifted",
    "unreachable": "controller.unreachable",
}
#: How bad each state is, for a robot's state (the worst of its tools'): an index into
#: ROBOT_STATES.
SEVERITY: dict[ToolState, int] = {
    "in_sync": 0,
    "no_active_version": 0,
    "not_live": 0,
    "drifted": 1,
    "unreachable": 2,
}


def frame_json(data: ToolData | None) -> JsonObject | None:
    """A frame as stored and served: {"position_mm", "quaternion"}."""
    if data is None:
        return None
    return {"position_mm": list(data.position_mm), "quaternion": list(data.quaternion)}


@dataclass(frozen=True)
class Observation:
    """What one look at the controller found for one tool."""

    tool_id: str
    robot_id: str
    state: ToolState
    target: str | None
    controller: JsonObject | None
    active_version: int | None
    deviation_mm: float | None
    deviation_deg: float | None
    error: str | None


def observe(
    session: Session, seen: Observation, *, at: datetime, actor: Principal
) -> tuple[ToolControllerState, bool]:
    """Store what was seen; (the state row, whether the state changed). The tool's row is
    locked first, so two instances looking at once record one change, not two."""
    session.execute(select(Tool.id).where(Tool.id == seen.tool_id).with_for_update())
    row = session.get(ToolControllerState, seen.tool_id)
    changed = row is None or row.state != seen.state
    previous = None if row is None else row.state
    if row is None:
        row = ToolControllerState(tool_id=seen.tool_id, robot_id=seen.robot_id)
        session.add(row)
    if changed:
        row.state = seen.state
        row.since = at
    row.robot_id = seen.robot_id
    row.checked_at = at
    row.target = seen.target
    row.controller = seen.controller
    row.active_version = seen.active_version
    row.deviation_mm = seen.deviation_mm
    row.deviation_deg = seen.deviation_deg
    row.error = seen.error
    action = EVENT_ACTIONS.get(seen.state) if changed else None
    if action is not None:
        audit.record(
            session,
            actor=actor,
            action=action,
            resource_type="tool",
            resource_id=seen.tool_id,
            robot_id=seen.robot_id,
            tool_id=seen.tool_id,
            version=seen.active_version,
            details={
                "previous_state": previous,
                "target": seen.target,
                "version": seen.active_version,
                "controller": seen.controller,
                "deviation_mm": seen.deviation_mm,
                "deviation_deg": seen.deviation_deg,
                "error": seen.error,
            },
        )
    session.flush()
    return row, action is not None


def not_live(tool_id: str, robot_id: str, target: str | None, version: int | None) -> Observation:
    """A tool of a robot with one live TCP (a `live` scope protocol: `ur_rtde`, `techman`) that is
    not the one deployed to it last: not judged against what the controller holds."""
    return Observation(
        tool_id=tool_id,
        robot_id=robot_id,
        state="not_live",
        target=target,
        controller=None,
        active_version=version,
        deviation_mm=None,
        deviation_deg=None,
        error=None,
    )


def others_not_live(
    session: Session,
    *,
    robot_id: str,
    live_tool_id: str,
    target: str,
    at: datetime,
    actor: Principal,
) -> None:
    """A `live` scope deployment made `live_tool_id` the robot's one live TCP: its other live
    tools are `not_live` from then on (the reconcile rounds judge the tool deployed last)."""
    others = session.execute(
        select(Tool.id, Tool.active_version)
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None), Tool.id != live_tool_id)
        .order_by(Tool.id)
    ).all()
    for tool_id, version in others:
        observe(session, not_live(tool_id, robot_id, target, version), at=at, actor=actor)
