"""Which frame a fleet row's robot moves in, as SQL on the row's Frame (contract v1.4,
"Frames at the controller"): one table of cases, so that the `live` a frame's row shows, its
attention codes and `?attention=` are the same conditions, each a primary-key seek in
robot_live_frames (app.services.robots.live_frame records it, with the one match).

The cases, first that holds: `unread` (no round read the frame: a controller that does not
say, a failed read, never reconciled); `active` (the match is this frame's active version);
`stale_version` (the match is another version of this frame); `other_frame` (the match is
another frame's version); else `unknown` (no version of the robot's frames equals it).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

from sqlalchemy import ScalarSelect, and_, case, exists, null, or_, select, true
from sqlalchemy.orm import InstrumentedAttribute, aliased

from app.schemas.frames import FleetFrameLive
from app.services.lifecycle.fleet import RowPart, live_cells
from app.storage.models import Frame, RobotLiveFrame

T = TypeVar("T")


def _robot_live(column: InstrumentedAttribute[T]) -> ScalarSelect[T]:
    """`column` of the row's robot's live frame, correlated to Frame (a primary-key seek)."""
    return (
        select(column)
        .where(RobotLiveFrame.robot_id == Frame.robot_id)
        .correlate(Frame)
        .scalar_subquery()
    )


_MATCH_FRAME = _robot_live(RobotLiveFrame.frame_id)
_MATCH_VERSION = _robot_live(RobotLiveFrame.version)
_NUMBER = _robot_live(RobotLiveFrame.number)
# The cases in order (the first that holds is the row's), each written once.
_UNREAD = _robot_live(RobotLiveFrame.read).is_not(true())
_THIS_FRAME = Frame.id == _MATCH_FRAME
_ACTIVE = and_(_THIS_FRAME, Frame.active_version == _MATCH_VERSION)
_OTHER = _MATCH_FRAME.is_not(None)
LIVE_STATE = case(
    (_UNREAD, "unread"),
    (_ACTIVE, "active"),
    (_THIS_FRAME, "stale_version"),
    (_OTHER, "other_frame"),
    else_="unknown",
)

_HOLDER = aliased(Frame, name="frame_slot_holder")
#: The frame an unknown live frame is blamed on: the one whose slot is the live frame number
#: (a controller that numbers its frames); when the controller names no number (one that
#: names frames by value, or by name only) or no live frame of the robot has that slot,
#: every frame of the robot (any may be the one it moves in), as a tool's UNKNOWN_TCP_HERE.
UNKNOWN_FRAME_HERE = or_(
    Frame.slot == _NUMBER,
    ~exists(
        select(_HOLDER.id)
        .where(
            _HOLDER.robot_id == Frame.robot_id,
            _HOLDER.archived_at.is_(None),
            _HOLDER.slot == _NUMBER,
        )
        .correlate(Frame)
    ),
)


def _fleet_live(values: Sequence[object]) -> FleetFrameLive:
    state, version, frame_id, checked_at, number, name = values
    unread = state == "unread"
    return FleetFrameLive.model_validate(
        {
            "state": state,
            "version": None if unread else version,
            "frame_id": None if unread else frame_id,
            "checked_at": checked_at,
            "number": None if unread else number,
            "name": None if unread else name,
        }
    )


#: A frame's fleet rows' `live` (app.services.lifecycle.fleet.RowPart): which frame its robot
#: moves in, and the two attention codes read from it.
FRAME_LIVE = RowPart(
    field="live",
    columns=(
        LIVE_STATE.label("live_state"),
        case((_UNREAD, null()), else_=_MATCH_VERSION).label("live_version"),
        case((_UNREAD, null()), else_=_MATCH_FRAME).label("live_frame_id"),
        _robot_live(RobotLiveFrame.checked_at).label("live_checked_at"),
        _NUMBER.label("live_number"),
        _robot_live(RobotLiveFrame.name).label("live_name"),
    ),
    read=_fleet_live,
    rules={
        # What the last reconcile round read of the frame the robot moves in.
        "moving_in_stale_frame": LIVE_STATE == "stale_version",
        "moving_in_unknown_frame": and_(LIVE_STATE == "unknown", UNKNOWN_FRAME_HERE),
    },
    csv_names=("live_state", "live_version", "live_checked_at"),
    csv_cells=live_cells,
)
