"""Which TCP a fleet row's robot moves by, as SQL on the row's Tool (contract v1.3 fleet
`live`): one table of cases, so that the `live` a row shows, its attention codes and
`?attention=` are the same conditions, each a seek in robot_live_tools or the primary key of
robot_live_matches (robot_id, tool_id, version).

The cases, first that holds: `unread` (no round read a frame: a controller that names no live
TCP, a connector without read_pose, a failed read, never reconciled); `active` (a match is
this tool's active version); `stale_version` (a match is another version of this tool: the
newest such); `other_tool` (a match is another tool's version); else `unknown` (no version
has the frame: `no_tool` when it is the bare flange, no tool selected).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

from sqlalchemy import (
    ColumnElement,
    Exists,
    ScalarSelect,
    and_,
    case,
    exists,
    null,
    or_,
    select,
    true,
)
from sqlalchemy.orm import InstrumentedAttribute, aliased

from app.schemas.fleet import FleetLive
from app.services.lifecycle.fleet import RowPart, live_cells
from app.storage.models import RobotLiveMatch, RobotLiveTool, Tool

T = TypeVar("T")


def _robot_live(column: InstrumentedAttribute[T]) -> ScalarSelect[T]:
    """`column` of the row's robot's live tool, correlated to Tool (a primary-key seek)."""
    return (
        select(column)
        .where(RobotLiveTool.robot_id == Tool.robot_id)
        .correlate(Tool)
        .scalar_subquery()
    )


def _matches(*conditions: ColumnElement[bool]) -> Exists:
    return (
        select(RobotLiveMatch.version)
        .where(RobotLiveMatch.robot_id == Tool.robot_id, *conditions)
        .correlate(Tool)
        .exists()
    )


def _first_match(
    column: InstrumentedAttribute[T], *conditions: ColumnElement[bool]
) -> ScalarSelect[T]:
    """`column` of the match the row names: the newest version, of the first tool by id."""
    return (
        select(column)
        .where(RobotLiveMatch.robot_id == Tool.robot_id, *conditions)
        .order_by(RobotLiveMatch.tool_id, RobotLiveMatch.version.desc())
        .limit(1)
        .correlate(Tool)
        .scalar_subquery()
    )


_THIS_TOOL = RobotLiveMatch.tool_id == Tool.id
# The cases in order (the first that holds is the row's), each written once.
_UNREAD = _robot_live(RobotLiveTool.read).is_not(true())
_ACTIVE = _matches(_THIS_TOOL, RobotLiveMatch.version == Tool.active_version)
_STALE = _matches(_THIS_TOOL)
_OTHER = _matches()
LIVE_STATE = case(
    (_UNREAD, "unread"),
    (_ACTIVE, "active"),
    (_STALE, "stale_version"),
    (_OTHER, "other_tool"),
    else_="unknown",
)
LIVE_VERSION = case(
    (_UNREAD, null()),
    (_ACTIVE, Tool.active_version),
    (_STALE, _first_match(RobotLiveMatch.version, _THIS_TOOL)),
    (_OTHER, _first_match(RobotLiveMatch.version)),
    else_=null(),
)
LIVE_TOOL_ID = case(
    (_UNREAD, null()),
    (_ACTIVE, Tool.id),
    (_STALE, Tool.id),
    (_OTHER, _first_match(RobotLiveMatch.tool_id)),
    else_=null(),
)
LIVE_CHECKED_AT = _robot_live(RobotLiveTool.checked_at)
#: The tool number the controller reported (null where it names none).
LIVE_NUMBER = _robot_live(RobotLiveTool.number)
#: The robot moves by its bare flange: no tool selected (tool 0, a null tool, a zero TCP
#: offset: app.services.robots.live_tool.bare_flange), not an unknown TCP: it raises no
#: moving_by_unknown_tcp.
AT_FLANGE = _robot_live(RobotLiveTool.flange).is_(true())

_HOLDER = aliased(Tool, name="slot_holder")
#: The tool an unknown TCP is blamed on: the one whose slot is the live tool number (a
#: controller that numbers its tools); when the controller names no number or no live tool
#: has that slot, every tool of the robot (any of them may be the one it moves by).
UNKNOWN_TCP_HERE = or_(
    Tool.slot == _robot_live(RobotLiveTool.number),
    ~exists(
        select(_HOLDER.id)
        .where(
            _HOLDER.robot_id == Tool.robot_id,
            _HOLDER.archived_at.is_(None),
            _HOLDER.slot == _robot_live(RobotLiveTool.number),
        )
        .correlate(Tool)
    ),
)


def _fleet_live(values: Sequence[object]) -> FleetLive:
    state, version, tool_id, checked_at, number, flange = values
    return FleetLive.model_validate(
        {
            "state": state,
            "version": version,
            "tool_id": tool_id,
            "checked_at": checked_at,
            "number": None if state == "unread" else number,
            "no_tool": state == "unknown" and bool(flange),
        }
    )


#: A tool's fleet rows' `live` (app.services.lifecycle.fleet.RowPart): which TCP its robot
#: moves by, and the two attention codes read from it.
TOOL_LIVE = RowPart(
    field="live",
    columns=(
        LIVE_STATE.label("live_state"),
        LIVE_VERSION.label("live_version"),
        LIVE_TOOL_ID.label("live_tool_id"),
        LIVE_CHECKED_AT.label("live_checked_at"),
        LIVE_NUMBER.label("live_number"),
        AT_FLANGE.label("live_flange"),
    ),
    read=_fleet_live,
    rules={
        # What the last reconcile round read of the TCP the robot moves by.
        "moving_by_stale_version": LIVE_STATE == "stale_version",
        # (a robot at its bare flange has no tool selected: no unknown TCP)
        "moving_by_unknown_tcp": and_(LIVE_STATE == "unknown", UNKNOWN_TCP_HERE, ~AT_FLANGE),
    },
    csv_names=("live_state", "live_version", "live_checked_at"),
    csv_cells=live_cells,
)
