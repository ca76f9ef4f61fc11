"""The fleet view: every tool with its robot, its last calibration and its last check."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from app.schemas.common import StoredWord, Timestamp
from app.schemas.drift import FleetDrift
from app.vendors.registry import ACTIVE_TOOLS, BARE_FLANGES, LIVE_MAKER_OR, LIVE_TOOL_UNSAID
from app.words import Status, ToolState

#: The status a fleet row can be filtered by: its last calibration's.
CalibrationStatus = Status

#: The codes every subject's row has that judge its versions, calibrations, checks,
#: controller and drift (first in every subject's codes, in this order).
_JudgedCode = Literal[
    "active_out_of_tolerance",
    "last_calibration_out_of_tolerance",
    "check_failed",
    "no_active_version",
    "stale",
    "controller_drifted",
    "controller_unreachable",
    "drifting",
]

#: Why a tool's fleet row needs a person's attention: its codes, in the order rows list them (the
#: one list of them; each has its rule in app.services.fleet.fleet, `Fleet.rules`).
AttentionCode = Literal[
    _JudgedCode,
    "moving_by_stale_version",
    "moving_by_unknown_tcp",
    "frequent_corrections",
]

#: Why a frame's fleet row needs attention (GET /v1/frames): the codes a frame has, in the
#: order its rows list them; the frame's own `moving_in_*` are read from the frame its robot
#: moves in (app.services.frames.live), as a tool's `moving_by_*` from its live TCP.
FrameAttentionCode = Literal[
    _JudgedCode,
    "frequent_corrections",
    "moving_in_stale_frame",
    "moving_in_unknown_frame",
]
#: Any subject's attention code (a rule of app.services.fleet.fleet).
AnyAttentionCode = AttentionCode | FrameAttentionCode

#: What a fleet row's robot moves by, about the row's tool (contract v1.3).
LiveState = Literal["active", "stale_version", "other_tool", "unknown", "unread"]


class LastCalibration(BaseModel):
    id: str
    status: StoredWord[Status]
    created_at: Timestamp
    rms_mm: float | None


class LastCheck(BaseModel):
    id: str = Field(description="the check's id (its audit record)")
    within_tolerance: bool
    distance_mm: float
    created_at: Timestamp
    verdict: str | None = Field(
        default=None,
        description="within_tolerance | out_of_tolerance | corrected (the re-check found the "
        "TCP out of tolerance and made a new active version of it) | deployment_failed "
        "(corrected, and the correction's deployment failed) | recalibrate (checks recorded "
        "since v1.3; null before)",
    )
    correction_version: int | None = Field(
        default=None, description="the version a re-check corrected the TCP to, if it did"
    )


class FleetController(BaseModel):
    """What the last look at the robot's controller found for the tool."""

    state: ToolState = Field(
        description="in_sync | drifted | no_active_version | unreachable | not_live (its "
        f"robot has one live TCP, {LIVE_MAKER_OR}, and another tool was deployed to it last)"
    )
    checked_at: Timestamp
    deviation_mm: float | None = Field(description="controller vs active TCP: distance, mm")
    deviation_deg: float | None = Field(
        description="controller vs active TCP: angle between the orientations, deg (an "
        "orientation-only edit drifts with deviation_mm 0)"
    )
    version: int | None = Field(
        default=None,
        description="the version the controller was compared with at checked_at (the active "
        "one then); when it is not the row's active_version, the state is that version's, "
        "and nothing has compared the controller with the active one yet",
    )
    target: str | None = Field(
        default=None,
        description="where the controller holds the tool: $TOOL_DATA[3], UTOOL[3], "
        "TOOL.CND tool 3, a RAPID symbol, current TCP",
    )


class FleetLive(BaseModel):
    """Which TCP the row's robot moves by, as the last reconcile round read it."""

    state: LiveState = Field(
        description="active (this tool's active version), stale_version (an older version "
        "of this tool), other_tool (another tool's version), unknown (a frame no version "
        f"has), unread (the controller does not say, as {LIVE_TOOL_UNSAID}, or could not be "
        "read)"
    )
    version: int | None = Field(
        description="the version the robot moves by (of `tool_id`); null when unknown or unread"
    )
    tool_id: str | None = Field(
        description="the tool whose version it is: this row's, or another's for other_tool"
    )
    checked_at: Timestamp | None = Field(
        description="when a reconcile round (or a deployment to a robot with one live TCP, "
        "which reads it back) last read it; null when never"
    )
    number: int | None = Field(
        default=None,
        description=f"the tool number the controller reported ({ACTIVE_TOOLS}); null where it "
        "names none or was not read",
    )
    no_tool: bool = Field(
        default=False,
        description=f"true when the robot moves by its bare flange ({BARE_FLANGES}): no tool "
        "is selected, as robots idle between jobs; state is then unknown (no version has the "
        "flange's frame) and raises no moving_by_unknown_tcp",
    )


def _never_read() -> FleetLive:
    return FleetLive(state="unread", version=None, tool_id=None, checked_at=None)


class FleetTool(BaseModel):
    id: str
    name: str
    slot: int | None
    robot_id: str
    robot_name: str
    cell: str | None
    active_version: int | None
    last_calibration: LastCalibration | None
    last_check: LastCheck | None
    position_mm: list[float] | None = Field(
        default=None, description="the active TCP's position (mm); null without an active version"
    )
    quaternion: list[float] | None = Field(
        default=None,
        description="the active TCP's orientation [w, x, y, z]; null without an active version",
    )
    attention: list[AttentionCode] = Field(
        default_factory=list,
        description="why the tool needs attention, empty when all is well: "
        "active_out_of_tolerance (the version served was stored out of tolerance), "
        "last_calibration_out_of_tolerance, check_failed (the newest check found the TCP out "
        "of tolerance and did not correct it), "
        "no_active_version, stale (no calibration or check for TCPCAL_STALE_DAYS days), "
        "controller_drifted (the robot's controller holds another TCP than the active one), "
        "controller_unreachable (it could not be read at the last look), "
        "drifting (the drift trend leaves check_mm within 30 days at 95 % confidence), "
        "moving_by_stale_version (the robot moves by an older version of this tool), "
        "moving_by_unknown_tcp (it moves by a frame no version has, in this tool's slot or, "
        "where that is not known, by one of its robot's tools; not its bare flange, no tool "
        "selected), "
        "frequent_corrections (corrected by re-checks more than TCPCAL_CORRECTIONS_ALERT "
        "times, default 3, in 30 days: a tool that keeps getting hit)",
    )
    controller: FleetController | None = Field(
        default=None,
        description="the tool's state in its robot's controller at the last reconcile or "
        "deployment; null when never looked at",
    )
    drift: FleetDrift | None = Field(
        default=None,
        description="the TCP's drift trend (docs/drift.md); null until three points over a day",
    )
    live: FleetLive = Field(
        default_factory=_never_read,
        description="which TCP the tool's robot moves by right now",
    )


class CheckRecord(BaseModel):
    """A check as recorded: what the technician saw, read back."""

    id: str
    tool_id: str
    version: int | None
    reference_point_id: str | None
    deviation_mm: list[float] | None
    deviation_flange_mm: list[float] | None = None
    distance_mm: float
    check_mm: float | None
    within_tolerance: bool
    summary: str | None = Field(
        default=None, description="the verdict in one sentence (checks recorded since v1.1)"
    )
    verdict: str | None = Field(
        default=None,
        description="within_tolerance | out_of_tolerance | corrected | deployment_failed | "
        "recalibrate (checks recorded since v1.3)",
    )
    correction_version: int | None = Field(
        default=None, description="the version a re-check corrected the TCP to, if it did"
    )
    checked_at: Timestamp
    checked_by: str
