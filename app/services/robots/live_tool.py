"""Which TCP each robot moves by right now (contract v1.3, LiveTool): the versions of the
robot's tools that equal the tool frame its controller reports, and what the reconcile
rounds last found, one row a robot.

A version equals the live frame within SYNC_TOLERANCE_MM and SYNC_TOLERANCE_DEG, the
tolerances a reconcile finds a tool in sync by: a frame the controller holds is its
version when a reconcile would call them the same.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import delete, insert, select
from sqlalchemy.orm import Session

from app.helpers.frame_deviation import (
    SYNC_TOLERANCE_DEG,
    SYNC_TOLERANCE_MM,
    frame_deviation,
    within,
)
from app.jsontypes import JsonObject
from app.schemas.controllers import Frame as FrameOut
from app.schemas.controllers import LiveToolMatch, LiveToolOut
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.storage.models import Robot, RobotLiveMatch, RobotLiveTool, TcpVersion, Tool
from app.vendors.connector import Connector, ControllerError, ControllerRefused, Frame, LiveTool


def live_tool_matches(session: Session, robot_id: str, frame: Frame | None) -> list[LiveToolMatch]:
    """Every version of the robot's live tools whose frame equals `frame` (within 0.01 mm
    and 0.01 deg), oldest tool first and by version; none when the frame is not known. The
    caller limits the session to the robots its key may see (app.security.auth.act_for)."""
    if frame is None:
        return []
    rows = session.execute(
        select(
            TcpVersion.tool_id,
            TcpVersion.version,
            TcpVersion.position_mm,
            TcpVersion.quaternion,
            Tool.active_version,
        )
        .join(Tool, Tool.id == TcpVersion.tool_id)
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
        .order_by(Tool.created_at, Tool.id, TcpVersion.version)
    )
    return [
        LiveToolMatch(tool_id=tool_id, version=version, active=version == active)
        for tool_id, version, position_mm, quaternion, active in rows
        if within(
            frame_deviation(frame.position_mm, frame.quaternion, position_mm, quaternion),
            mm=SYNC_TOLERANCE_MM,
            deg=SYNC_TOLERANCE_DEG,
        )
    ]


def live_tool_out(live: LiveTool, matches: list[LiveToolMatch]) -> LiveToolOut:
    """A controller's LiveTool as served, with its matches (contract v1.3 LiveTool)."""
    frame = None
    if live.frame is not None:
        frame = FrameOut(
            position_mm=list(live.frame.position_mm), quaternion=list(live.frame.quaternion)
        )
    return LiveToolOut(number=live.number, frame=frame, matches=matches)


@dataclass(frozen=True)
class LiveRead:
    """What a reconcile round read of the tool the robot moves by: the controller's LiveTool,
    or None and why not."""

    tool: LiveTool | None
    error: str | None
    #: False when the round could not open a session with the controller (or lost it)
    reached: bool = True


def read_live(conn: Connector) -> LiveRead:
    """The live tool through the connector's read_pose, in the round's session. A failed
    read (a KUKA in external-TCP mode refuses it) leaves it unread, saying why; it never
    fails the round's tool states."""
    try:
        return LiveRead(conn.read_pose().live_tool, None)
    except ControllerRefused as exc:
        return LiveRead(None, f"refused: {exc.controller_message}")
    except ControllerError as exc:
        return LiveRead(None, str(exc))


#: The bare flange: the frame of tool 0 (KUKA $NULLFRAME, FANUC UTOOL 0, Yaskawa's tool 0 as
#: shipped, a zero UR tcp_offset, Techman's NOTOOL).
FLANGE = Frame((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))


def bare_flange(tool: LiveTool | None) -> bool:
    """True when the robot moves by its bare flange (within 0.01 mm and 0.01 deg) with no
    tool selected, as robots stand between jobs: not an unknown TCP. No tool is tool 0 or no
    number (KUKA $ACT_TOOL 0 and -1, FANUC UTOOL 0, UR, Techman); a job that selects tool 5
    holding zeros (a Yaskawa TOOL.CND block never filled in) moves by an unknown TCP."""
    if tool is None or tool.frame is None or tool.number not in (None, 0):
        return False
    frame = tool.frame
    deviation = frame_deviation(
        frame.position_mm, frame.quaternion, FLANGE.position_mm, FLANGE.quaternion
    )
    return within(deviation, mm=SYNC_TOLERANCE_MM, deg=SYNC_TOLERANCE_DEG)


def _frame_json(frame: Frame | None) -> JsonObject | None:
    if frame is None:
        return None
    return {"position_mm": list(frame.position_mm), "quaternion": list(frame.quaternion)}


def _same_frame(a: JsonObject | None, b: JsonObject | None) -> bool:
    if a is None or b is None:
        return a is b
    deviation = frame_deviation(
        a["position_mm"], a["quaternion"], b["position_mm"], b["quaternion"]
    )
    return within(deviation, mm=SYNC_TOLERANCE_MM, deg=SYNC_TOLERANCE_DEG)


def record_live(
    session: Session, *, robot_id: str, live: LiveRead, at: datetime, actor: Principal
) -> list[LiveToolMatch]:
    """Store what the round read of the robot's live tool and its matches (returned); a
    change is an audit event `robot.live_tool`, once. The robot's row is locked first, so
    two rounds meeting record one change."""
    session.execute(select(Robot.id).where(Robot.id == robot_id).with_for_update())
    frame = None if live.tool is None else live.tool.frame
    number = None if live.tool is None else live.tool.number
    matches = live_tool_matches(session, robot_id, frame)
    found = {(m.tool_id, m.version) for m in matches}
    row = session.get(RobotLiveTool, robot_id)
    stored = select(RobotLiveMatch.tool_id, RobotLiveMatch.version).where(
        RobotLiveMatch.robot_id == robot_id
    )
    before = {(tool_id, version) for tool_id, version in session.execute(stored)}
    frame_json = _frame_json(frame)
    changed = row is None or (
        (row.read, row.number, before) != (frame is not None, number, found)
        or not _same_frame(row.frame, frame_json)
    )
    previous = None if row is None else _live_details(row.read, row.number, row.frame, before)
    if row is None:
        row = RobotLiveTool(robot_id=robot_id)
        session.add(row)
    if changed:
        row.since = at
    row.read, row.number, row.frame = frame is not None, number, frame_json
    row.flange = bare_flange(live.tool)
    row.checked_at, row.error = at, live.error
    session.flush()
    if before != found:
        session.execute(delete(RobotLiveMatch).where(RobotLiveMatch.robot_id == robot_id))
        if found:
            session.execute(
                insert(RobotLiveMatch),
                [{"robot_id": robot_id, "tool_id": t, "version": v} for t, v in sorted(found)],
            )
    if changed:
        details = _live_details(frame is not None, number, frame_json, found)
        audit.record(
            session,
            actor=actor,
            action="robot.live_tool",  # a change of the tool the robot moves by
            resource_type="robot",
            resource_id=robot_id,
            robot_id=robot_id,
            details={
                **details,
                "matches": [m.model_dump() for m in matches],
                "error": live.error,
                "previous": previous,
            },
        )
    return matches


def _live_details(
    read: bool, number: int | None, frame: JsonObject | None, matches: set[tuple[str, int]]
) -> JsonObject:
    return {
        "read": read,
        "number": number,
        "frame": frame,
        "matches": [{"tool_id": t, "version": v} for t, v in sorted(matches)],
    }


def forget_live(session: Session, robot_id: str) -> None:
    """Drop what the rounds read of the robot's live tool (its controller is removed: the
    fleet stops saying what it moves by, as it stops saying what its controller holds)."""
    session.execute(delete(RobotLiveMatch).where(RobotLiveMatch.robot_id == robot_id))
    session.execute(delete(RobotLiveTool).where(RobotLiveTool.robot_id == robot_id))
