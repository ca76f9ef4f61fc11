"""Planning a touch set (POST /v1/plan) and guided sessions (calibrate touch by touch)."""

from __future__ import annotations

from typing import Annotated, Literal, Self

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.schemas.common import (
    Activate,
    FiniteFloat,
    LongText,
    Pose,
    PositiveFloat,
    ResourceId,
    StoredWord,
    StrictModel,
    Timestamp,
    TouchNoise,
    Units,
    Vec3,
    json_integer,
    not_both,
    one_of,
)
from app.schemas.results import TouchSource
from app.solvers.planning import MAX_TOUCHES, MIN_TOUCHES
from app.words import MethodName, PoseFormat, SessionStatus

TiltDeg = Annotated[
    float,
    Field(ge=0.0, le=90.0, allow_inf_nan=False, strict=True, description="max tilt (deg)"),
]
SpinDeg = Annotated[
    float,
    Field(ge=0.0, le=180.0, allow_inf_nan=False, strict=True, description="max |spin| (deg)"),
]
TouchCount = Annotated[int, Field(ge=MIN_TOUCHES, le=MAX_TOUCHES), json_integer]
DEFAULT_PLAN_TOUCHES = 6


class PlanRequest(StrictModel):
    model_config = ConfigDict(
        json_schema_extra=not_both(("n_poses", "target_sigma_mm"), ("tcp_mm", "tool_id"))
    )

    format: PoseFormat
    units: Units | None = None
    start: Pose = Field(
        description="one flange pose touching the point; its tool axis is the cone's centre"
    )
    tcp_mm: Vec3 | None = Field(
        default=None, description="approximate TCP (default: the tool's active TCP, else 0 0 150)"
    )
    tool_id: ResourceId | None = None
    touch_noise_mm: TouchNoise = 0.05
    max_tilt_deg: TiltDeg = 40.0
    max_spin_deg: SpinDeg = 90.0
    n_poses: TouchCount | None = Field(
        default=None, description=f"how many touches (default {DEFAULT_PLAN_TOUCHES})"
    )
    target_sigma_mm: PositiveFloat | None = Field(
        default=None,
        description="pick the fewest touches whose predicted_sigma_mm reaches this (mm)",
    )

    @model_validator(mode="after")
    def _one_of_each(self) -> PlanRequest:
        if self.n_poses is not None and self.target_sigma_mm is not None:
            raise ValueError("give n_poses or target_sigma_mm, not both")
        if self.tcp_mm is not None and self.tool_id is not None:
            raise ValueError("give tcp_mm or tool_id (its active TCP), not both")
        return self


class PlannedTouch(BaseModel):
    tilt_deg: float = Field(description="angle of the tool axis from the start's")
    azimuth_deg: float = Field(description="direction of the tilt in the start's flange x-y")
    spin_deg: float = Field(description="rotation about the tool axis")


class Plan(BaseModel):
    n_poses: int
    poses: list[Pose]
    predicted_tcp_sigma_mm: list[float] = Field(description="1-sigma per flange axis (mm)")
    predicted_sigma_mm: float = Field(description="sqrt(sx^2 + sy^2 + sz^2): RMS TCP error")
    criterion: Literal["A-optimal"] = Field(
        default="A-optimal", description="the touches minimise the trace of the TCP covariance"
    )
    touches: list[PlannedTouch] = Field(description="each pose as tilt, azimuth, spin")


class PoseOrCapture(StrictModel):
    """A touch's pose: typed, or read from the robot's controller (a tool session's touch
    and a frame session's, app.schemas.frame_sessions)."""

    model_config = ConfigDict(
        json_schema_extra=one_of((("pose",), ("capture",)), (("capture",), ("pose",)))
    )

    pose: Pose | None = Field(default=None, description="the touch, in the session's format")
    capture: Literal[True] | None = Field(
        default=None,
        description="true: read the touch from the tool's robot's controller (two reads "
        "100 ms apart that must agree) in place of `pose`",
    )

    @model_validator(mode="after")
    def _pose_or_capture(self) -> Self:
        if (self.pose is None) == (self.capture is None):
            raise ValueError(
                'give "pose" (a typed touch) or "capture": true (read it from the '
                "controller), one of the two"
            )
        return self


class TouchAdd(PoseOrCapture):
    format: PoseFormat | None = Field(
        default=None,
        description="the format the client holds `pose` in, when it says so: it must be the "
        "session's (422 at body.format otherwise; a touch is never converted)",
    )


class SessionFinish(StrictModel):
    activate: Activate = "auto"
    note: LongText | None = None


class Estimate(BaseModel):
    tcp_mm: list[float]
    tcp_sigma_mm: list[float]
    rms_mm: float


class NextTouch(BaseModel):
    """The suggested touch in words: how its orientation differs from the first touch's."""

    tilt_deg: float = Field(description="tilt of the tool axis (flange z) from the first touch's")
    lean_deg: float = Field(
        description="the direction the tool axis leans toward, in the first touch's flange x-y "
        "plane: 0 = +x, 90 = +y (0 when there is no tilt)"
    )
    spin_deg: float = Field(description="rotation about the tool axis, right-handed, -180..180")


class Session(BaseModel):
    id: str
    tool_id: str
    status: SessionStatus
    method: StoredWord[MethodName]
    format: StoredWord[PoseFormat]
    units: Units | None
    n_poses: int
    poses: list[Pose] = Field(description="the touches kept so far, in order (index from 0)")
    touches: list[TouchSource] = Field(description="where each pose came from, in order")
    estimate: Estimate | None
    outliers: list[int] = Field(
        description="0-based index into poses of each touch the others say was missed "
        "(touch n, as messages name it, is index n - 1)"
    )
    next_pose: list[FiniteFloat] | list[list[FiniteFloat]] | None = Field(
        description="the touch that shrinks the largest remaining uncertainty most, in the "
        "session's format; null before the first touch, when done or finished"
    )
    next_touch: NextTouch | None = Field(
        description="next_pose against the first touch, in words a person moves the robot by; "
        "null when next_pose is"
    )
    residuals_mm: list[float] | None = Field(
        description="each touch's distance (mm) from where the estimate puts the point, in "
        "order (a calibration's quality.residuals_mm); null without an estimate"
    )
    done: bool
    target_sigma_mm: float
    messages: list[str]
    calibration_id: str | None
    created_at: Timestamp
    updated_at: Timestamp
