"""Reference points, laser devices and TCP checks."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.jsontypes import JsonObject
from app.schemas.common import (
    FiniteFloat,
    Name,
    Pose,
    Poses,
    PositiveFloat,
    Reason,
    ResourceId,
    StoredWord,
    StrictModel,
    Timestamp,
    Units,
    Vec3,
    one_of,
)
from app.schemas.controllers import Deployment
from app.solvers.laser import Beam
from app.words import LaserDeviceSource, PoseFormat


#: One sweep through a laser beam (the laser_beam method's input and a laser check's).
class SweepIn(StrictModel):
    beam: Beam
    break_mm: Vec3
    restore_mm: Vec3


Matrix3 = Annotated[list[Vec3], Field(min_length=3, max_length=3)]


class TouchIn(StrictModel):
    """A touch of the point by a tool whose active TCP is trusted."""

    tool_id: ResourceId
    format: PoseFormat
    pose: Pose
    units: Units | None = None


def _numbers_or_touch_schema() -> JsonObject:
    """Numbers (source "numeric" if given) or a touch (source "touch"), never both."""
    extra = one_of((("position_mm",), ("touch",)), (("touch",), ("position_mm", "covariance_mm2")))
    for alternative, source in zip(extra["oneOf"], ("numeric", "touch"), strict=True):
        alternative["properties"]["source"] = {"enum": [source, None]}
    return extra


class ReferencePointCreate(StrictModel):
    model_config = ConfigDict(json_schema_extra=_numbers_or_touch_schema())

    name: Name
    position_mm: Vec3 | None = None
    covariance_mm2: Matrix3 | None = None
    source: Literal["numeric", "touch"] | None = None
    touch: TouchIn | None = None

    @model_validator(mode="after")
    def _numbers_or_touch(self) -> ReferencePointCreate:
        if (self.position_mm is None) == (self.touch is None):
            raise ValueError("give position_mm (numeric entry) or touch (a trusted tool's touch)")
        if self.touch is not None and self.covariance_mm2 is not None:
            raise ValueError("a touched point's covariance is computed; do not give one")
        given_by = "touch" if self.touch is not None else "numeric"
        if self.source is not None and self.source != given_by:
            raise ValueError(f"source {self.source!r} does not match what was given ({given_by})")
        return self


class ReferencePoint(BaseModel):
    id: str
    robot_id: str
    name: str
    position_mm: list[float]
    covariance_mm2: list[list[float]] | None
    source: str
    calibration_id: str | None
    created_at: Timestamp
    created_by: str


class CheckCreate(StrictModel):
    """Touches of the point typed (`format` and `poses`), or one read from the tool's
    robot's controller (`capture`: true)."""

    model_config = ConfigDict(
        json_schema_extra=one_of(
            (("format", "poses"), ("capture",)), (("capture",), ("format", "poses", "units"))
        )
    )

    reference_point_id: ResourceId
    format: PoseFormat | None = None
    poses: Annotated[Poses, Field(min_length=1)] | None = None
    units: Units | None = None
    capture: Literal[True] | None = Field(
        default=None,
        description="true: touch the point once and read the pose from the controller (two "
        "reads 100 ms apart that must agree) in place of `format` and `poses`",
    )
    correct: Literal["never", "within_limits"] = Field(
        default="never",
        description='"within_limits" (with `capture`): a deviation beyond check_mm and within '
        "the tool's max_correction_mm is corrected: a new version by xyz_reference from the "
        "one touch (orientation kept), activated with kind check_correction, then deployed",
    )
    deploy: bool | None = Field(
        default=None,
        description="deploy the correction to the robot's controller and read it back "
        "(default: true when correcting)",
    )
    reason: Reason | None = Field(
        default=None, description="why (e.g. the collision), kept with the correction's activation"
    )

    @model_validator(mode="after")
    def _typed_or_captured(self) -> CheckCreate:
        typed = self.format is not None and self.poses is not None
        if self.capture is not None:
            if self.format is not None or self.poses is not None or self.units is not None:
                raise ValueError(
                    '"capture": true reads the pose from the controller: leave out format, '
                    "poses and units"
                )
        elif not typed:
            raise ValueError(
                'give "format" and "poses" (typed touches) or "capture": true (read from '
                "the controller)"
            )
        return self


class CheckTouch(BaseModel):
    deviation_mm: list[float]
    deviation_flange_mm: list[float]
    distance_mm: float


#: What came of a check: in tolerance; out of it and not corrected (correct: never); corrected
#: (and deployed, or not asked to); corrected but the deployment failed; beyond
#: max_correction_mm, so nothing changed and the tool needs recalibrating.
CheckVerdict = Literal[
    "within_tolerance", "out_of_tolerance", "corrected", "deployment_failed", "recalibrate"
]


class Correction(BaseModel):
    version: int = Field(description="the new version, active (kind check_correction)")
    previous_version: int = Field(description="the version the check measured")
    delta_mm: list[float] = Field(
        description="new TCP minus the checked one, flange frame, mm (dx, dy, dz)"
    )
    deployment: Deployment | None = Field(
        description="the deployment of the new version (its status: verified, not_written, "
        "unverified, mismatch); null when not deployed"
    )


class CheckResult(BaseModel):
    tool_id: str
    version: int
    reference_point_id: str
    deviation_mm: list[float] = Field(
        description="where the tool tip is minus where the active TCP puts it, r - (R t + f), "
        "for the worst touch (largest distance), base frame, mm"
    )
    deviation_flange_mm: list[float] = Field(
        description="the same deviation in the flange frame: how the tool moved since the "
        "active version, new TCP minus active TCP (+Y: the tip moved along flange +Y), mm"
    )
    distance_mm: float = Field(description="|deviation_mm|: what within_tolerance compares")
    mean_deviation_mm: list[float] = Field(description="mean deviation over the touches, base")
    check_mm: float
    within_tolerance: bool
    touches: list[CheckTouch]
    summary: str = Field(
        description="the verdict, which way the tool moved and what was done about it"
    )
    verdict: CheckVerdict = Field(
        description="within_tolerance | out_of_tolerance (not corrected) | corrected | "
        "deployment_failed (corrected, active, not on the controller) | recalibrate (beyond "
        "max_correction_mm: nothing changed)",
    )
    correction: Correction | None = Field(
        default=None, description="the correction made; null when none was"
    )
    checked_at: Timestamp
    checked_by: str


class LaserTeachIn(StrictModel):
    """Sweeps and descent by a tool whose active TCP (and axis) is trusted."""

    tool_id: ResourceId
    format: PoseFormat
    poses: Annotated[Poses, Field(min_length=1, max_length=1)]
    units: Units | None = None
    sweeps: Annotated[list[SweepIn], Field(min_length=4, max_length=200)]
    descent_mm: Vec3
    trigger_noise_mm: PositiveFloat | None = None


class LaserDeviceCreate(StrictModel):
    model_config = ConfigDict(
        json_schema_extra=one_of(
            (("beam_a_y_mm", "beam_b_x_mm", "plane_z_mm"), ("teach",)),
            (("teach",), ("beam_a_y_mm", "beam_b_x_mm", "plane_z_mm")),
        )
    )

    name: Name
    beam_a_y_mm: FiniteFloat | None = None
    beam_b_x_mm: FiniteFloat | None = None
    plane_z_mm: FiniteFloat | None = None
    teach: LaserTeachIn | None = None

    @model_validator(mode="after")
    def _numbers_or_teach(self) -> LaserDeviceCreate:
        numbers = [self.beam_a_y_mm, self.beam_b_x_mm, self.plane_z_mm]
        if self.teach is None and any(n is None for n in numbers):
            raise ValueError("give beam_a_y_mm, beam_b_x_mm and plane_z_mm, or teach")
        if self.teach is not None and any(n is not None for n in numbers):
            raise ValueError("a taught device's geometry is computed; give teach alone")
        return self


class LaserDevice(BaseModel):
    id: str
    robot_id: str
    name: str
    beam_a_y_mm: float
    beam_b_x_mm: float
    plane_z_mm: float
    source: StoredWord[LaserDeviceSource]
    details: JsonObject | None
    created_at: Timestamp
    created_by: str
