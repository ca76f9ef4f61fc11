"""A frame's re-check after a move (contract v1.4 "After a move: re-register"): the stored
fiducials touched again, the rigid shift found, each fiducial's deviation in the frame's axes,
and what was done about it."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field

from app.schemas.common import (
    Pose,
    Reason,
    ResourceId,
    StrictModel,
    Timestamp,
    Units,
    Vec3,
)
from app.schemas.frame_results import FramePointer
from app.words import PoseFormat

FrameCheckVerdict = Literal["within_tolerance", "corrected", "needs_recalibration"]
FrameCheckScope = Literal["frame", "robot"]


class FiducialTouch(StrictModel):
    """One stored fiducial touched again: its name (GET /v1/frames/{frame_id}/fiducials) and
    the flange pose in the body's `format`."""

    fiducial: Annotated[str, Field(min_length=1, max_length=100)] = Field(
        description="the stored fiducial touched (its name at GET /v1/frames/{frame_id}/fiducials)"
    )
    pose: Pose = Field(description="the flange pose with the pointer on it, in the body's format")


class FrameCheckCreate(StrictModel):
    tool_id: ResourceId = Field(description="the pointer tool whose active TCP touched the points")
    format: PoseFormat = Field(description="the format of every touch's pose")
    units: Units | None = Field(default=None, description="the poses' units, when not the format's")
    touches: Annotated[list[FiducialTouch], Field(min_length=3, max_length=200)] = Field(
        description="at least three of the frame's stored fiducials, each touched again"
    )
    correct: Literal["never", "within_limits"] = Field(
        default="never",
        description='"within_limits": a largest fiducial deviation past check_mm and none past '
        "max_correction_mm corrects the frame: a new version carried by the shift, activated "
        "with kind check_correction and `reason`",
    )
    deploy: bool | None = Field(
        default=None,
        description="deploy the correction to the robot's controller (default: true when "
        "correcting, where frames can be deployed)",
    )
    reason: Reason | None = Field(
        default=None, description="why (e.g. the fixture was unbolted), kept with the activation"
    )
    scope: FrameCheckScope = Field(
        default="frame",
        description='"robot": the robot itself moved; the same shift corrects every frame and '
        "reference point of the robot, each with its reason, in one transaction",
    )


class FiducialDeviation(BaseModel):
    fiducial: str = Field(description="the fiducial touched")
    deviation_mm: Vec3 = Field(
        description="where it is now minus where it was, in the frame's axes"
    )
    distance_mm: float = Field(description="how far it moved, mm")
    words: str = Field(description="the deviation in a sentence")


class FrameShift(BaseModel):
    """The rigid move that carries the stored fiducials onto the touches (base frame)."""

    position_mm: Vec3 = Field(description="the shift's translation, base frame")
    angle_deg: float = Field(description="the shift's rotation angle")
    axis: Vec3 = Field(description="the unit axis of the shift's rotation, base frame")
    position_sigma_mm: Vec3 = Field(description="1-sigma of the translation per base axis")
    angle_sigma_deg: Vec3 = Field(description="1-sigma of the small rotations about x, y, z")
    rms_mm: float = Field(description="rms of the fiducials' residuals after the shift")


class MovedSubject(BaseModel):
    """A frame or reference point a robot-scope correction moved."""

    kind: Literal["frame", "reference_point"] = Field(description="what was moved")
    id: str = Field(description="its id")
    name: str = Field(description="its name")
    version: int | None = Field(description="the frame's new version (null: a reference point)")
    moved_mm: float = Field(description="how far its origin (or the point) moved")
    deployment: dict[str, object] | None = Field(
        default=None,
        description="the frame's new version's deployment (null: a reference point, or none "
        "made; the summary says why)",
    )


class FrameCorrection(BaseModel):
    version: int = Field(description="the new version, active (kind check_correction)")
    previous_version: int = Field(description="the version that was checked")
    deployment: dict[str, object] | None = Field(
        default=None,
        description="the deployment made of the new version (null: none made; the summary "
        "says why)",
    )
    moved: list[MovedSubject] = Field(
        default_factory=list,
        description='scope "robot": every other frame and reference point the shift moved',
    )


class FrameCheck(BaseModel):
    id: str = Field(
        description="the check's id (its audit event's check_id, and the note of "
        "the versions it made)"
    )
    frame_id: str = Field(description="the frame checked")
    robot_id: str = Field(description="its robot")
    version: int = Field(description="the frame's version checked (its active one)")
    scope: FrameCheckScope = Field(description='"frame", or "robot": the robot itself moved')
    tool: FramePointer = Field(description="the pointer tool and the TCP version used")
    deviations: list[FiducialDeviation] = Field(description="each fiducial touched, in order")
    shift: FrameShift = Field(
        description="the best rigid fit of the stored fiducials to the touches"
    )
    verdict: FrameCheckVerdict = Field(
        description="within_tolerance (largest deviation within check_mm), corrected (a new "
        "version active), or needs_recalibration (nothing changed: beyond max_correction_mm, "
        'or past check_mm without "correct": "within_limits")'
    )
    correction: FrameCorrection | None = Field(description="what was changed (null: nothing)")
    differs_from: list[str] = Field(
        default_factory=list,
        description="another frame's check of this robot within the hour whose shift differs "
        "from this one (said, not averaged)",
    )
    summary: str = Field(description="the check and what was done, in words")
    created_at: Timestamp = Field(description="when it was checked")
    created_by: str = Field(description="the API key that checked it")
