"""Reconcile a robot: read every live tool's frame from its controller and compare it with
the tool's active version (in sync within 0.01 mm and 0.01 deg).

As for deployments, the controller is read with no database transaction open; the states
found are then stored in one write transaction, each change of a tool's state an audit event.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.auth import Principal, act_for
from app.controllers import connect
from app.controllers.base import (
    ControllerError,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    ToolData,
    ToolTarget,
    describe_target,
    target_problem,
)
from app.db import session_scope
from app.helpers.frames import SYNC_TOLERANCE_DEG, SYNC_TOLERANCE_MM, frame_deviation, within
from app.metrics import CONTROLLER_STATE_CHANGES, RECONCILES
from app.models import Robot, RobotController, TcpVersion, Tool, utcnow
from app.schemas.controllers import Reconciliation
from app.services import controller_states, settling
from app.services.controller_states import SEVERITY, Observation
from app.services.controllers import get_controller, refusal_words, settings_of
from app.services.live_tool import LiveRead, live_tool_out, read_live, record_live
from app.services.robots import get_robot
from app.statuses import ROBOT_STATES, ToolState


@dataclass(frozen=True)
class ToolToCheck:
    """A live tool, where it lives in the controller and its active frame (if any)."""

    tool_id: str
    target: ToolTarget | None  # None: the tool has no place in this controller
    target_name: str | None
    problem: str | None
    version: int | None
    position_mm: list[float] | None
    quaternion: list[float] | None


@dataclass(frozen=True)
class Reading:
    """What the controller held for a tool, or why it could not be read."""

    data: ToolData | None
    error: str | None


def _tools_to_check(session: Session, robot_id: str, protocol: str) -> list[ToolToCheck]:
    rows = session.execute(
        select(Tool.id, Tool.slot, Tool.controller_symbol, TcpVersion)
        .outerjoin(
            TcpVersion,
            (TcpVersion.tool_id == Tool.id) & (TcpVersion.version == Tool.active_version),
        )
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
        .order_by(Tool.created_at, Tool.id)
    )
    tools = []
    for tool_id, slot, symbol, version in rows:
        target = ToolTarget(slot=slot, symbol=symbol)
        problem = target_problem(protocol, target)
        tools.append(
            ToolToCheck(
                tool_id=tool_id,
                target=None if problem else target,
                target_name=None if problem else describe_target(protocol, target),
                problem=problem,
                version=None if version is None else version.version,
                position_mm=None if version is None else list(version.position_mm),
                quaternion=None if version is None else list(version.quaternion),
            )
        )
    return tools


def read_controller(
    settings: ControllerSettings, tools: list[ToolToCheck], *, robot_id: str
) -> tuple[dict[str, Reading], LiveRead]:
    """Each addressable tool's frame as the controller holds it, then the tool the robot
    moves by (one session; no database). A tool the controller refuses to read is
    unreachable with its words; a connection that fails makes every tool not yet read
    unreachable and the live tool unread."""
    readings: dict[str, Reading] = {}
    todo = [t for t in tools if t.target is not None]
    live = LiveRead(None, None)
    try:
        with connect(settings) as conn:
            for tool in todo:
                assert tool.target is not None
                try:
                    readings[tool.tool_id] = Reading(conn.read_tool(tool.target), None)
                except ControllerRefused as exc:
                    words = refusal_words(exc, robot_id)
                    readings[tool.tool_id] = Reading(None, f"refused: {words}")
            live = read_live(conn)
    except (ControllerUnreachable, ControllerRefused, ControllerError) as exc:
        words = refusal_words(exc, robot_id) if isinstance(exc, ControllerRefused) else str(exc)
        where = settings.where()
        for tool in todo:
            readings.setdefault(tool.tool_id, Reading(None, f"{where}: {words}"))
        live = LiveRead(None, f"{where}: {words}")
    return readings, live


def _observation(robot_id: str, tool: ToolToCheck, reading: Reading) -> Observation:
    """The state of one tool from what the controller held."""
    held = reading.data
    deviation = None
    state: ToolState
    if held is None:
        state = "unreachable"
    elif tool.version is None or tool.position_mm is None or tool.quaternion is None:
        state = "no_active_version"
    else:
        deviation = frame_deviation(
            tool.position_mm, tool.quaternion, held.position_mm, held.quaternion
        )
        ok = within(deviation, mm=SYNC_TOLERANCE_MM, deg=SYNC_TOLERANCE_DEG)
        state = "in_sync" if ok else "drifted"
    return Observation(
        tool_id=tool.tool_id,
        robot_id=robot_id,
        state=state,
        target=tool.target_name,
        controller=controller_states.frame_json(held),
        active_version=tool.version,
        deviation_mm=None if deviation is None else deviation[0],
        deviation_deg=None if deviation is None else deviation[1],
        error=reading.error,
    )


def reconcile_robot(
    *,
    robot_id: str,
    actor: Principal,
    trigger: str = "api",
    cancelled: Callable[[], bool] = lambda: False,
) -> Reconciliation | None:
    """Read the robot's controller, compare with every live tool's active version, store
    the states; 404 for the robot, 409 when it has no controller. None when `cancelled()`
    turned true while the controller was read (a stopping watcher stores nothing)."""
    with session_scope(write=False) as session:
        act_for(session, actor)  # only the robots the key's cells hold
        get_robot(session, robot_id)
        controller = get_controller(session, robot_id)
        settings = settings_of(controller)
        tools = _tools_to_check(session, robot_id, controller.protocol)
    read_from = utcnow()
    readings, live = read_controller(settings, tools, robot_id=robot_id)
    if cancelled():
        return None
    checked_at = utcnow()
    entered: list[ToolState] = []
    found: list[ToolState] = []
    answer_tools: list[dict[str, object]] = []
    skipped: list[dict[str, object]] = []
    with session_scope(write=True) as session:
        act_for(session, actor)  # only the robots the key's cells hold
        # first: it locks the robot's row before the tools' (the order every writer keeps),
        # and the round's tool states and live tool commit together
        matches = record_live(session, robot_id=robot_id, live=live, at=checked_at, actor=actor)
        for tool in tools:
            if tool.target is None:
                skipped.append({"tool_id": tool.tool_id, "reason": tool.problem})
                continue
            seen = _observation(robot_id, tool, readings[tool.tool_id])
            row, changed = controller_states.observe(session, seen, at=checked_at, actor=actor)
            settling.settle(session, seen, read_from=read_from, at=checked_at, actor=actor)
            found.append(seen.state)
            if changed:
                entered.append(seen.state)
            answer_tools.append(_tool_answer(tool, seen, row.since))
    for state in entered:
        CONTROLLER_STATE_CHANGES.labels(state).inc()
    robot_state = ROBOT_STATES[max((SEVERITY[state] for state in found), default=0)]
    RECONCILES.labels(trigger, robot_state).inc()
    return Reconciliation.model_validate(
        {
            "robot_id": robot_id,
            "checked_at": checked_at,
            "state": robot_state,
            "tools": answer_tools,
            "not_addressable": skipped,
            "live_tool": None if live.tool is None else live_tool_out(live.tool, matches),
            "live_tool_error": live.error,
        }
    )


def _tool_answer(tool: ToolToCheck, seen: Observation, since: object) -> dict[str, object]:
    active = None
    if tool.version is not None:
        active = {
            "version": tool.version,
            "position_mm": tool.position_mm,
            "quaternion": tool.quaternion,
        }
    return {
        "tool_id": tool.tool_id,
        "target": tool.target_name,
        "state": seen.state,
        "controller": seen.controller,
        "active": active,
        "deviation_mm": seen.deviation_mm,
        "deviation_deg": seen.deviation_deg,
        "since": since,
        "error": seen.error,
    }


def robots_with_controller() -> list[str]:
    """Ids of the live robots that have a controller (the watcher's round)."""
    with session_scope(write=False) as session:
        return list(
            session.scalars(
                select(RobotController.robot_id)
                .join(Robot, Robot.id == RobotController.robot_id)
                .where(Robot.archived_at.is_(None))
                .order_by(RobotController.robot_id)
            )
        )
