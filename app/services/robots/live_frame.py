"""Which frame each robot moves in right now (contract v1.4, "Frames at the controller": "a
robot's live base is named where the controller says"): what the round's pose read says
of it (app.vendors.connector.LiveFrame, from the same read as the live tool) and the version
of one of the robot's frames that equals it, one row a robot (robot_live_frames), beside
its live tool (app.services.robots.live_tool).

A version equals the live frame within SYNC_TOLERANCE_MM and SYNC_TOLERANCE_DEG, as a tool's
version equals its live TCP. The match is a frame's active version when one is; else the
newest version of the first frame (by creation) that equals it, an older one: the robot
moves in a stale frame; none: in an unknown frame.
"""

from __future__ import annotations

from datetime import datetime
from typing import NamedTuple, cast

from sqlalchemy import Table, bindparam, delete, insert, select, update
from sqlalchemy.orm import Session

from app.helpers.frame_deviation import SYNC_TOLERANCE_DEG, SYNC_TOLERANCE_MM, frames_within
from app.jsontypes import JsonObject
from app.storage.db import DriverWrite, HeldRead
from app.storage.models import Frame, FrameVersion, RobotLiveFrame
from app.vendors.connector import Frame as Pose
from app.vendors.connector import LiveFrame


class _Version(NamedTuple):
    """A version of one of the robot's frames."""

    frame_id: str
    version: int
    active_version: int | None
    position_mm: list[float]
    quaternion: list[float]


#: The versions of the robot's live frames, oldest frame first and newest version first
#: (a round runs it for every robot: on the driver's cursor).
_VERSIONS = HeldRead(
    _Version,
    select(FrameVersion.frame_id, FrameVersion.version, Frame.active_version)
    .add_columns(FrameVersion.position_mm, FrameVersion.quaternion)
    .join(Frame, Frame.id == FrameVersion.frame_id)
    .where(Frame.robot_id == bindparam("robot_id"), Frame.archived_at.is_(None))
    .order_by(Frame.created_at, Frame.id, FrameVersion.version.desc()),
)
_TABLE = cast(Table, RobotLiveFrame.__table__)


class _Last(NamedTuple):
    """What the last round stored of the robot's live frame."""

    read: bool
    number: int | None
    name: str | None
    frame_id: str | None
    version: int | None


_LAST = HeldRead(
    _Last,
    select(
        _TABLE.c.read, _TABLE.c.number, _TABLE.c.name, _TABLE.c.frame_id, _TABLE.c.version
    ).where(_TABLE.c.robot_id == bindparam("robot_id")),
)
#: What a round writes of the robot's live frame (`since` too when it changed): on the
#: driver's cursor, as record_live's (through Session.execute, the UPDATE built anew each
#: round was a seventh of what storing a robot's round cost the watcher).
_WRITTEN = (*_Last._fields, "frame", "checked_at")
_BY_ROBOT = _TABLE.c.robot_id == bindparam("robot")
_INSERT = DriverWrite(insert(_TABLE))
_UPDATE = DriverWrite(update(_TABLE).where(_BY_ROBOT).values({c: bindparam(c) for c in _WRITTEN}))
_UPDATE_SINCE = DriverWrite(
    update(_TABLE).where(_BY_ROBOT).values({c: bindparam(c) for c in (*_WRITTEN, "since")})
)


def live_frame_match(session: Session, robot_id: str, frame: Pose | None) -> tuple[str, int] | None:
    """(frame_id, version) of the robot's live frames' version equal to `frame`: an active
    version first, else the newest version of the oldest frame; None when none equals it
    or the frame is not known."""
    if frame is None:
        return None
    at = (frame.position_mm, frame.quaternion)
    matches = [
        (frame_id, version, version == active)
        for frame_id, version, active, *value in _VERSIONS.all_in(session, robot_id=robot_id)
        if frames_within(*at, *value, mm=SYNC_TOLERANCE_MM, deg=SYNC_TOLERANCE_DEG)
    ]
    if not matches:
        return None
    frame_id, version, _ = next((m for m in matches if m[2]), matches[0])
    return frame_id, version


def record_live_frame(session: Session, *, robot_id: str, live: LiveFrame, at: datetime) -> None:
    """Store what the round read of the frame the robot moves in and its match; `since`
    moves when the number, name or match changes. The caller holds the robot's row locked
    (record_live locks it first in the round's transaction). Core statements, as
    record_live's, on the driver's cursor (a round stores one a robot): an ORM copy of the
    row is expired."""
    match = live_frame_match(session, robot_id, live.frame)
    frame_id, version = match if match is not None else (None, None)
    value: JsonObject | None = None
    if live.frame is not None:
        value = {
            "position_mm": list(live.frame.position_mm),
            "quaternion": list(live.frame.quaternion),
        }
    read = live.frame is not None or live.number is not None or live.name is not None
    last = _LAST.one_or_none_in(session, robot_id=robot_id)
    now = (read, live.number, live.name, frame_id, version)
    values: dict[str, object] = dict(zip(_Last._fields, now, strict=True))
    values |= {"frame": value, "checked_at": at}
    if last is None:
        _INSERT.execute(session, [{"robot_id": robot_id, "since": at, **values}])
    elif tuple(last) != now:
        _UPDATE_SINCE.execute(session, [{"robot": robot_id, "since": at, **values}])
    else:
        _UPDATE.execute(session, [{"robot": robot_id, **values}])
    copy = session.identity_map.get(session.identity_key(RobotLiveFrame, robot_id))
    if copy is not None:
        session.expire(copy)


def forget_live_frame(session: Session, robot_id: str) -> None:
    """Drop what the rounds read of the frame the robot moves in (its controller is removed,
    as its live tool is forgotten)."""
    session.execute(delete(RobotLiveFrame).where(RobotLiveFrame.robot_id == robot_id))
