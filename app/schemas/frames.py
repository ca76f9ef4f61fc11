"""Frames (contract v1.4 "Frames"): a robot's bases and fixed tools, their versions and the
served active frame. A frame's value is a pose in the robot's base (world) frame."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, BeforeValidator, Field

from app.schemas.common import (
    LongText,
    Name,
    Quaternion,
    StoredWord,
    StrictModel,
    Timestamp,
    Vec3,
    json_integer,
)
from app.schemas.controllers import ControllerSymbol
from app.schemas.drift import FleetDrift
from app.schemas.fleet import (
    FleetController,
    FrameAttentionCode,
    LastCalibration,
    LastCheck,
)
from app.schemas.frame_results import Fiducial, FramePointer, FrameQuality, FrameValue
from app.schemas.frame_tolerance import FrameTolerance
from app.schemas.tools import ActivationOut, ControllerText
from app.words import FrameKind, FrameMethodName, Status

FrameSlot = Annotated[
    int,
    Field(ge=0, le=10_000, description="the controller's frame number"),
    BeforeValidator(json_integer),
]
_SYMBOL = (
    "where a controller naming frames by symbol keeps this frame: its RAPID wobjdata (a base) "
    'or tooldata with robhold FALSE (a fixed tool), "TASK/MODULE/SYMBOL"'
)


class FrameCreate(StrictModel):
    name: Name
    kind: FrameKind
    slot: FrameSlot | None = None
    controller_symbol: ControllerSymbol | None = Field(default=None, description=_SYMBOL)
    description: LongText | None = None
    tolerance: FrameTolerance = Field(default_factory=FrameTolerance)


class FrameUpdate(StrictModel):
    name: Name | None = None
    slot: FrameSlot | None = None
    controller_symbol: ControllerSymbol | None = Field(default=None, description=_SYMBOL)
    description: LongText | None = None
    tolerance: FrameTolerance | None = None


class RobotFrame(BaseModel):
    id: str
    robot_id: str
    name: str
    kind: StoredWord[FrameKind]
    slot: int | None
    controller_symbol: str | None = Field(default=None, description=_SYMBOL)
    description: str | None
    tolerance: FrameTolerance
    active_version: int | None
    created_at: Timestamp
    updated_at: Timestamp


class FramePose(BaseModel):
    """A frame in the robot's base frame: its origin (mm) and orientation [w, x, y, z]; for a
    fixed tool, the stationary TCP."""

    position_mm: Vec3
    quaternion: Quaternion = Field(default_factory=lambda: [1.0, 0.0, 0.0, 0.0])


class FrameVersion(BaseModel):
    version: int
    frame: FramePose
    source: StoredWord[FrameMethodName]
    status: StoredWord[Status]
    calibration_id: str | None
    note: str | None
    created_at: Timestamp
    created_by: str
    active: bool


class FrameVersionList(BaseModel):
    items: list[FrameVersion]
    activations: list[ActivationOut] = Field(default_factory=list)


class ActiveRobotFrame(BaseModel):
    frame_id: str
    robot_id: str
    frame_name: str
    slot: int | None
    version: int
    frame: FramePose
    calibrated_at: Timestamp
    method: StoredWord[FrameMethodName]
    controller: ControllerText | None = None
    controller_error: dict[str, str] | None = Field(
        default=None, description="why this frame has no text in the requested format"
    )


class FrameTable(BaseModel):
    robot_id: str
    items: list[ActiveRobotFrame]
    without_active_version: list[str] = Field(
        default_factory=list, description="ids of frames that have no active version"
    )


class FrameCalibration(BaseModel):
    """A frame calibration as stored: what its method made of the touches, graded against
    the frame's tolerance, and the version it became."""

    id: str
    frame_id: str
    method: StoredWord[FrameMethodName]
    status: StoredWord[Status]
    frame: FrameValue
    quality: FrameQuality
    points_mm: list[list[float]] = Field(description="each touch's point (mm, base frame)")
    tool: FramePointer | None = Field(description="the pointer tool; null for manual")
    warnings: list[str]
    summary: str = Field(description="what was done and how well, in words")
    fiducials: list[Fiducial] = Field(
        description="the touched points kept, in the new frame's coordinates"
    )
    version: int | None = Field(description="the frame version it became")
    active: bool = Field(description="whether that version is the frame's active one")
    change_from_active_mm: float | None = Field(
        description="the largest move of a fiducial (the origin, without any) from the frame "
        "active before (mm); null when none was"
    )
    change_from_active_deg: float | None = Field(
        description="the rotation from the frame active before (deg); null when none was"
    )
    created_at: Timestamp
    created_by: str


FiducialName = Annotated[str, Field(min_length=1, max_length=100, pattern=r"^[^\x00-\x1f\x7f]+$")]


class FiducialNames(StrictModel):
    """New names for the active calibration's fiducials, one per fiducial in its order."""

    names: list[FiducialName] = Field(
        min_length=1, max_length=1000, description="each fiducial's new name, in order"
    )


class FiducialList(BaseModel):
    frame_id: str
    calibration_id: str | None = Field(
        description="the calibration of the active version they were kept by (null: none)"
    )
    items: list[Fiducial]


#: What a frame's row says of the frame its robot moves in: `active` (this frame's active
#: version), `stale_version` (an older version of this frame), `other_frame` (a version of
#: another frame of the robot), `unknown` (no version of its frames), `unread` (no round read it).
FrameLiveState = Literal["active", "stale_version", "other_frame", "unknown", "unread"]


class FleetFrameLive(BaseModel):
    state: FrameLiveState = Field(
        description="active | stale_version (an older version of this frame) | other_frame "
        "(a version of another frame of the robot) | unknown (no version of its frames) | "
        "unread (no round read the frame it moves in)"
    )
    version: int | None = Field(description="the version the robot moves in, if one matches")
    frame_id: str | None = Field(description="the frame whose version matches, if one does")
    checked_at: Timestamp | None = Field(description="when the round read it")
    number: int | None = Field(description="the frame number the controller reported")
    name: str | None = Field(description="the frame name the controller reported")


class FleetFrame(BaseModel):
    """A frame as a fleet row (GET /v1/frames): every field the fleet fills for every subject
    (app.services.lifecycle.fleet.FleetSide), and the frame's kind and slot."""

    id: str
    name: str
    kind: StoredWord[FrameKind]
    slot: int | None
    robot_id: str
    robot_name: str
    cell: str | None
    active_version: int | None
    last_calibration: LastCalibration | None
    last_check: LastCheck | None
    position_mm: list[float] | None = Field(
        default=None,
        description="the active frame's origin (mm, base frame); null without an active version",
    )
    quaternion: list[float] | None = Field(
        default=None,
        description="the active frame's orientation [w, x, y, z]; null without an active version",
    )
    attention: list[FrameAttentionCode] = Field(
        default_factory=list,
        description="why the frame needs attention, empty when all is well: a tool's row's "
        "codes that judge its versions, calibrations, checks and controller, and "
        "moving_in_stale_frame (the robot moves in an older version of this frame) and "
        "moving_in_unknown_frame (it moves in a frame no version of its frames has, at this "
        "frame's slot)",
    )
    live: FleetFrameLive | None = Field(
        default=None,
        description="the frame the robot moves in, as the last reconcile round read it, "
        "about this frame",
    )
    controller: FleetController | None = Field(
        default=None,
        description="the frame's state in its robot's controller; null until frames are "
        "deployed and reconciled",
    )
    drift: FleetDrift | None = Field(
        default=None,
        description="the frame's drift trend over its calibrated versions (docs/drift.md); "
        "null until three points over a day",
    )
