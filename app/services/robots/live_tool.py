"""Which TCP each robot moves by right now (contract v1.3, LiveTool): the versions of the
robot's tools that equal the tool frame its controller reports, and what the reconcile
rounds last found, one row a robot.

A version equals the live frame within SYNC_TOLERANCE_MM and SYNC_TOLERANCE_DEG, the
tolerances a reconcile finds a tool in sync by: a frame the controller holds is its
version when a reconcile would call them the same.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple

from sqlalchemy import bindparam, delete, insert, select, update
from sqlalchemy.orm import Session

from app.helpers.frame_deviation import SYNC_TOLERANCE_DEG, SYNC_TOLERANCE_MM, frames_within
from app.jsontypes import JsonObject
from app.schemas.controllers import Frame as FrameOut
from app.schemas.controllers import LiveToolMatch, LiveToolOut
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.storage.db import DriverWrite, HeldRead
from app.storage.models import Robot, RobotLiveMatch, RobotLiveTool, TcpVersion, Tool, table_of
from app.vendors.connector import (
    UNREAD_FRAME,
    Connector,
    ControllerError,
    ControllerRefused,
    Frame,
    LiveFrame,
    LiveTool,
)

_LIVE = table_of(RobotLiveTool)
_MATCHES = table_of(RobotLiveMatch)


class _Version(NamedTuple):
    """A version of one of the robot's live tools (the matches' candidates)."""

    tool_id: str
    version: int
    position_mm: list[float]
    quaternion: list[float]
    active_version: int | None


#: Every version of the robot's live tools, oldest tool first and by version (a read each
#: round of every robot whose controller says its frame: on the driver's cursor).
_VERSIONS = HeldRead(
    _Version,
    select(
        TcpVersion.tool_id,
        TcpVersion.version,
        TcpVersion.position_mm,
        TcpVersion.quaternion,
        Tool.active_version,
    )
    .join(Tool, Tool.id == TcpVersion.tool_id)
    .where(Tool.robot_id == bindparam("robot_id"), Tool.archived_at.is_(None))
    .order_by(Tool.created_at, Tool.id, TcpVersion.version),
)


def live_tool_matches(session: Session, robot_id: str, frame: Frame | None) -> list[LiveToolMatch]:
    """Every version of the robot's live tools whose frame equals `frame` (within 0.01 mm
    and 0.01 deg), oldest tool first and by version; none when the frame is not known. The
    caller limits the session to the robots its key may see (app.security.auth.act_for)."""
    if frame is None:
        return []
    return [
        LiveToolMatch(tool_id=v.tool_id, version=v.version, active=v.version == v.active_version)
        for v in _VERSIONS.all_in(session, robot_id=robot_id)
        if _in_sync(frame.position_mm, frame.quaternion, v.position_mm, v.quaternion)
    ]


def _in_sync(
    position_a_mm: Sequence[float],
    quaternion_a: Sequence[float],
    position_b_mm: Sequence[float],
    quaternion_b: Sequence[float],
) -> bool:
    """Two frames the same as a reconcile judges them (0.01 mm and 0.01 deg)."""
    return frames_within(
        position_a_mm,
        quaternion_a,
        position_b_mm,
        quaternion_b,
        mm=SYNC_TOLERANCE_MM,
        deg=SYNC_TOLERANCE_DEG,
    )


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
    #: the frame the robot moves in, from the same read (app.services.robots.live_frame)
    frame: LiveFrame = UNREAD_FRAME


def read_live(conn: Connector) -> LiveRead:
    """The live tool through the connector's read_pose, in the round's session. A failed
    read (a controller in a mode that refuses it, as an external-TCP mode) leaves it unread,
    saying why; it never fails the round's tool states."""
    try:
        reading = conn.read_pose()
        return LiveRead(reading.live_tool, None, frame=reading.live_frame)
    except ControllerRefused as exc:
        return LiveRead(None, f"refused: {exc.controller_message}")
    except ControllerError as exc:
        return LiveRead(None, str(exc))


#: The bare flange: the frame of tool 0, or of no tool (each maker's null tool or zero TCP
#: offset, as its declaration in app/vendors/<maker>/ describes it).
FLANGE = Frame((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))


def bare_flange(tool: LiveTool | None) -> bool:
    """True when the robot moves by its bare flange (within 0.01 mm and 0.01 deg) with no
    tool selected, as robots stand between jobs: not an unknown TCP. No tool is tool 0 or no
    number (a controller's tool 0, or one that numbers no tools); a job that selects tool 5
    holding zeros (a tool block never filled in) moves by an unknown TCP."""
    if tool is None or tool.frame is None or tool.number not in (None, 0):
        return False
    frame = tool.frame
    return _in_sync(frame.position_mm, frame.quaternion, FLANGE.position_mm, FLANGE.quaternion)


def _frame_json(frame: Frame | None) -> JsonObject | None:
    if frame is None:
        return None
    return {"position_mm": list(frame.position_mm), "quaternion": list(frame.quaternion)}


def _same_frame(a: JsonObject | None, b: JsonObject | None) -> bool:
    if a is None or b is None:
        return a is b
    return _in_sync(a["position_mm"], a["quaternion"], b["position_mm"], b["quaternion"])


class _Stored(NamedTuple):
    """A row of _LOCK: the robot, what the last round stored of its live tool (all None
    before its first) and one of its stored matches (None: none), a row per match."""

    id: str
    read: bool | None
    number: int | None
    frame: JsonObject | None
    match_tool_id: str | None
    match_version: int | None


#: The robot's row locked, with what the last round stored of its live tool and its
#: matches: one statement, on the driver's cursor (a reconcile round of every robot runs it).
_LOCK = HeldRead(
    _Stored,
    select(
        Robot.id,
        RobotLiveTool.read,
        RobotLiveTool.number,
        RobotLiveTool.frame,
        RobotLiveMatch.tool_id.label("match_tool_id"),
        RobotLiveMatch.version.label("match_version"),
    )
    .select_from(Robot)
    .outerjoin(RobotLiveTool, RobotLiveTool.robot_id == Robot.id)
    .outerjoin(RobotLiveMatch, RobotLiveMatch.robot_id == Robot.id)
    .where(Robot.id == bindparam("robot_id"))
    .with_for_update(of=Robot),
)
_BY_ROBOT = _LIVE.c.robot_id == bindparam("robot")
_READ = ("read", "number", "frame", "flange", "checked_at", "error")
#: What a round writes of a robot's live tool: `since` too when it changed.
_UPDATE = DriverWrite(update(_LIVE).where(_BY_ROBOT).values({c: bindparam(c) for c in _READ}))
_UPDATE_SINCE = DriverWrite(
    update(_LIVE).where(_BY_ROBOT).values({c: bindparam(c) for c in (*_READ, "since")})
)
_INSERT = DriverWrite(insert(_LIVE))
_INSERT_MATCHES = DriverWrite(insert(_MATCHES))


@dataclass(frozen=True)
class _Last:
    """What the last round stored of a robot's live tool."""

    read: bool
    number: int | None
    frame: JsonObject | None


def _lock_last(session: Session, robot_id: str) -> tuple[_Last | None, set[tuple[str, int]]]:
    """Lock the robot's row; what the last round stored of its live tool (None before the
    first) and its stored matches."""
    rows = _LOCK.all_in(session, robot_id=robot_id)
    matches = {
        (r.match_tool_id, r.match_version)
        for r in rows
        if r.match_tool_id is not None and r.match_version is not None
    }
    read = rows[0].read if rows else None
    if read is None:
        return None, matches
    return _Last(read, rows[0].number, rows[0].frame), matches


def _write_live(
    session: Session, robot_id: str, values: dict[str, object], *, last: _Last | None, at: datetime
) -> None:
    """The robot's live-tool row as read now: inserted, or updated (`since` too when it
    changed: `values` then carry it)."""
    if last is None:
        _INSERT.execute(session, [{"robot_id": robot_id, **values, "since": at}])
    elif "since" in values:
        _UPDATE_SINCE.execute(session, [{"robot": robot_id, **values}])
    else:
        _UPDATE.execute(session, [{"robot": robot_id, **values}])


def _write_matches(
    session: Session, robot_id: str, before: set[tuple[str, int]], found: set[tuple[str, int]]
) -> None:
    """The robot's stored matches replaced by `found`, when they differ."""
    if before == found:
        return
    session.execute(delete(RobotLiveMatch).where(RobotLiveMatch.robot_id == robot_id))
    if found:
        _INSERT_MATCHES.execute(
            session,
            [{"robot_id": robot_id, "tool_id": t, "version": v} for t, v in sorted(found)],
        )


def record_live(
    session: Session, *, robot_id: str, live: LiveRead, at: datetime, actor: Principal
) -> list[LiveToolMatch]:
    """Store what the round read of the robot's live tool and its matches (returned); a
    change is an audit event `robot.live_tool`, once. The robot's row is locked first, so
    two rounds meeting record one change. Core statements on the driver's cursor (a round of
    every robot with a controller stores one each): pending ORM changes are written first."""
    session.flush()
    last, before = _lock_last(session, robot_id)
    frame = None if live.tool is None else live.tool.frame
    number = None if live.tool is None else live.tool.number
    matches = live_tool_matches(session, robot_id, frame)
    found = {(m.tool_id, m.version) for m in matches}
    frame_json = _frame_json(frame)
    changed = last is None or (
        (last.read, last.number, before) != (frame is not None, number, found)
        or not _same_frame(last.frame, frame_json)
    )
    values: dict[str, object] = {
        "read": frame is not None,
        "number": number,
        "frame": frame_json,
        "flange": bare_flange(live.tool),
        "checked_at": at,
        "error": live.error,
    }
    _write_live(session, robot_id, values | ({"since": at} if changed else {}), last=last, at=at)
    _write_matches(session, robot_id, before, found)
    if changed:
        previous = (
            None if last is None else _live_details(last.read, last.number, last.frame, before)
        )
        audit.record(
            session,
            actor=actor,
            action="robot.live_tool",  # a change of the tool the robot moves by
            resource_type="robot",
            resource_id=robot_id,
            robot_id=robot_id,
            details={
                **_live_details(frame is not None, number, frame_json, found),
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
