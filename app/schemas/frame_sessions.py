"""Guided frame sessions (API.md v1.4 "Sessions:"): a frame calibrated touch by touch, each
touch typed or captured, the next one said in words, finished as a frame calibration."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, Field, model_validator

from app.schemas.common import (
    Pose,
    PositiveFloat,
    Reason,
    ResourceId,
    StoredWord,
    StrictModel,
    Timestamp,
    TouchNoise,
    Units,
    Vec3,
)
from app.schemas.frame_checks import FrameCheckScope
from app.schemas.results import TouchSource
from app.schemas.sessions import PoseOrCapture
from app.words import (
    FrameRole,
    FrameSessionMethod,
    FrameTouchTakes,
    PoseFormat,
    SessionStatus,
    ThreePointConvention,
)


class FrameSessionOptions(StrictModel):
    """The frame method's options a session hands to its calibration (each method reads
    those it takes: GET /v1/methods)."""

    touch_noise_mm: TouchNoise | None = Field(
        default=None,
        description="1-sigma per axis of a touch (mm); default: the frame's tolerance's",
    )
    max_angle_sigma_deg: PositiveFloat | None = Field(
        default=None, description="the method's angle limit (1-sigma, deg)"
    )
    convention: ThreePointConvention | None = Field(
        default=None, description="three_point: whose three-point teach (default origin_x_xy)"
    )
    correct: Literal["never", "within_limits"] | None = Field(
        default=None, description="recheck: the check's `correct` (POST /v1/frames/{id}/checks)"
    )
    deploy: bool | None = Field(default=None, description="recheck: the check's `deploy`")
    reason: Reason | None = Field(default=None, description="recheck: the check's `reason`")
    scope: FrameCheckScope | None = Field(default=None, description="recheck: the check's `scope`")


class FrameSessionCreate(StrictModel):
    method: FrameSessionMethod = Field(
        description='a frame method that takes touches, or "recheck": the frame\'s stored '
        "fiducials touched again, finished as the frame's check"
    )
    tool_id: ResourceId = Field(
        description="the pointer tool the touches are made with (a tool of the frame's robot)"
    )
    format: PoseFormat
    units: Units | None = None
    options: FrameSessionOptions = Field(default_factory=FrameSessionOptions)


class FrameTouchAdd(PoseOrCapture):
    """One touch of a frame session: what it is (its role, or its nominal_mm), and its pose,
    typed or captured."""

    role: FrameRole | None = Field(
        default=None, description="which point this touch is (the session's next_role says)"
    )
    nominal_mm: Vec3 | None = Field(
        default=None, description="fit_points: the touched point's coordinates in the frame"
    )
    fiducial: Annotated[str, Field(min_length=1, max_length=100)] | None = Field(
        default=None,
        description="recheck: the stored fiducial touched (the session's next_role names the next)",
    )

    @model_validator(mode="after")
    def _role_or_nominal(self) -> FrameTouchAdd:
        given = [self.role, self.nominal_mm, self.fiducial]
        if sum(v is not None for v in given) > 1:
            raise ValueError(
                'give "role", "nominal_mm" or "fiducial" as the method takes, one of them'
            )
        return self


class FrameSessionTouch(TouchSource):
    role: FrameRole | None = Field(description="the role it was touched as; null: none")
    fiducial: str | None = Field(default=None, description="recheck: the fiducial touched")
    nominal_mm: list[float] | None = Field(description="fit_points: its point in the frame")
    pose: Pose
    point_mm: list[float] | None = Field(
        description="the touched point in the robot's base frame (flange x the pointer's "
        "active TCP); null when the pointer has none"
    )


class FrameEstimate(BaseModel):
    """The frame the touches so far give, as the calibration would compute it."""

    position_mm: list[float]
    quaternion: list[float] = Field(description="[w, x, y, z], frame -> base")
    position_sigma_mm: list[float] | None = Field(
        description="1-sigma of the origin per base axis (mm), as the calibration reports it"
    )
    angle_sigma_deg: list[float] | None = Field(
        description="1-sigma of the rotation about the frame's x, y, z (deg)"
    )
    summary: str = Field(description="the method's sentence on what the touches give")


class NextFrameTouch(BaseModel):
    role: str | None = Field(description="the role to send with the next touch; null: none")
    takes: FrameTouchTakes = Field(description="what the next touch is sent with beside its pose")


class FrameSession(BaseModel):
    id: str
    frame_id: str
    tool_id: str = Field(description="the pointer tool")
    status: SessionStatus
    method: StoredWord[FrameSessionMethod]
    format: StoredWord[PoseFormat]
    units: Units | None
    options: FrameSessionOptions
    n_touches: int = Field(description="how many touches are kept")
    touches: list[FrameSessionTouch] = Field(description="the touches kept so far, in order")
    next_role: str | None = Field(
        description="the next touch in words; null when the method takes no more"
    )
    next: NextFrameTouch | None = Field(
        description="what to send with the next touch; null when the method takes no more"
    )
    done: bool = Field(description="the touches can be finished (POST .../finish)")
    estimate: FrameEstimate | None = Field(
        description="the frame the touches give so far; null until they give one"
    )
    messages: list[str] = Field(description="what the touches say so far, in sentences")
    calibration_id: str | None = Field(description="the frame calibration its finish stored")
    created_at: Timestamp
    updated_at: Timestamp
