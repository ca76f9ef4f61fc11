"""Calibration submissions (one model per method, chosen by `method`) and results."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.schemas.common import (
    FiniteFloat,
    LongText,
    Name,
    NonNegativeFloat,
    Pose,
    PoseFormat,
    Poses,
    PositiveFloat,
    Quaternion,
    ResourceId,
    StrictModel,
    Timestamp,
    Units,
    Vec3,
)
from app.schemas.robots import Kinematics
from app.schemas.tools import Tcp, Tolerance

Activate = Literal["auto", "always", "never"]
Axis = Literal["+z", "-z", "+x", "-x"]
AxisName = Literal["x", "y", "z"]
SignedAxis = Literal["+x", "-x", "+y", "-y", "+z", "-z"]


class _Submission(StrictModel):
    format: PoseFormat | None = None
    poses: Poses | None = None
    units: Units | None = None
    activate: Activate = "auto"
    note: LongText | None = None


class _PosesRequired(_Submission):
    format: PoseFormat
    poses: Poses


# ---- xyz_npoint -----------------------------------------------------------------------------
class NPointOptions(StrictModel):
    algorithm: Literal["robust", "stacked", "pairwise", "sphere", "gls"] = "robust"
    touch_noise_mm: PositiveFloat | None = None
    orientation_noise_deg: NonNegativeFloat | None = None
    save_reference_point: Name | None = None


class XyzNpointCalibration(_PosesRequired):
    method: Literal["xyz_npoint"]
    options: NPointOptions = Field(default_factory=NPointOptions)


# ---- xyz_reference --------------------------------------------------------------------------
class ReferenceOptions(StrictModel):
    reference_point_id: ResourceId | None = None
    reference_tool_id: ResourceId | None = None
    reference_pose: Pose | None = None
    reference_point_mm: Vec3 | None = None
    touch_noise_mm: PositiveFloat | None = None

    @model_validator(mode="after")
    def _one_source(self) -> ReferenceOptions:
        sources = [
            self.reference_point_id is not None,
            self.reference_tool_id is not None or self.reference_pose is not None,
            self.reference_point_mm is not None,
        ]
        if sum(sources) != 1:
            raise ValueError(
                "give exactly one of reference_point_id, reference_tool_id + reference_pose, "
                "or reference_point_mm"
            )
        if (self.reference_tool_id is None) != (self.reference_pose is None):
            raise ValueError("reference_tool_id and reference_pose go together")
        return self


class XyzReferenceCalibration(_PosesRequired):
    method: Literal["xyz_reference"]
    options: ReferenceOptions


# ---- tcp_z_x --------------------------------------------------------------------------------
class DirectionIn(StrictModel):
    axis: Axis
    from_: Pose = Field(alias="from")
    to: Pose

    model_config = ConfigDict(extra="forbid", populate_by_name=True)


class TcpZxOptions(NPointOptions):
    pass


class TcpZxCalibration(_PosesRequired):
    method: Literal["tcp_z_x"]
    directions: Annotated[list[DirectionIn], Field(min_length=1, max_length=4)]
    options: TcpZxOptions = Field(default_factory=TcpZxOptions)


# ---- abc_2point / abc_world -----------------------------------------------------------------
class Abc2PointOptions(StrictModel):
    working_axis: Literal["x", "z"] = "x"
    tcp_mm: Vec3 | None = None
    touch_noise_mm: PositiveFloat | None = None


class Abc2PointCalibration(_PosesRequired):
    method: Literal["abc_2point"]
    options: Abc2PointOptions = Field(default_factory=Abc2PointOptions)


class AbcWorldOptions(StrictModel):
    align: dict[AxisName, SignedAxis] = Field(
        description='tool axis -> base axis, e.g. {"x": "-z"} (5D) or {"x": "-z", "y": "+y"}',
        min_length=1,
        max_length=2,
    )
    working_axis: Literal["x", "z"] = "x"
    tcp_mm: Vec3 | None = None


class AbcWorldCalibration(_PosesRequired):
    method: Literal["abc_world"]
    options: AbcWorldOptions


# ---- laser_beam -----------------------------------------------------------------------------
class LaserGeometry(StrictModel):
    device_id: ResourceId | None = None
    beam_a_y_mm: FiniteFloat | None = None
    beam_b_x_mm: FiniteFloat | None = None
    plane_z_mm: FiniteFloat | None = None

    @model_validator(mode="after")
    def _device_or_numbers(self) -> LaserGeometry:
        numbers = [self.beam_a_y_mm, self.beam_b_x_mm, self.plane_z_mm]
        if self.device_id is not None and any(n is not None for n in numbers):
            raise ValueError("give device_id or the three beam numbers, not both")
        if self.device_id is None and any(n is None for n in numbers):
            raise ValueError("give device_id, or all of beam_a_y_mm, beam_b_x_mm, plane_z_mm")
        return self


class SweepIn(StrictModel):
    beam: Literal["a", "b"]
    break_mm: Vec3
    restore_mm: Vec3


class LaserOptions(StrictModel):
    trigger_noise_mm: PositiveFloat | None = None


class LaserBeamCalibration(_PosesRequired):
    method: Literal["laser_beam"]
    laser: LaserGeometry
    sweeps: Annotated[list[SweepIn], Field(min_length=4, max_length=200)]
    descent_mm: Vec3
    options: LaserOptions = Field(default_factory=LaserOptions)


# ---- manual ---------------------------------------------------------------------------------
class ManualTcpIn(StrictModel):
    position_mm: Vec3
    quaternion: Quaternion | None = None


class ManualCalibration(_Submission):
    method: Literal["manual"]
    tcp: ManualTcpIn | None = None
    options: dict[str, Any] = Field(default_factory=dict, max_length=0)

    @model_validator(mode="after")
    def _tcp_or_pose(self) -> ManualCalibration:
        has_pose = self.poses is not None or self.format is not None
        if (self.tcp is None) == (not has_pose):
            raise ValueError("give either tcp, or format + poses with exactly one pose")
        if has_pose and (self.format is None or self.poses is None or len(self.poses) != 1):
            raise ValueError("manual with format + poses takes exactly one pose: the tool frame")
        return self


CalibrationRequest = Annotated[
    XyzNpointCalibration
    | XyzReferenceCalibration
    | TcpZxCalibration
    | Abc2PointCalibration
    | AbcWorldCalibration
    | LaserBeamCalibration
    | ManualCalibration,
    Field(discriminator="method"),
]
METHOD_NAMES = (
    "xyz_npoint",
    "xyz_reference",
    "tcp_z_x",
    "abc_2point",
    "abc_world",
    "laser_beam",
    "manual",
)


# ---- stateless solve: the same bodies plus what the method needs without a database ---------
class _Stateless(StrictModel):
    robot_id: ResourceId | None = None
    kinematics: Kinematics | None = None
    tolerance: Tolerance | None = None


class SolveXyzNpoint(XyzNpointCalibration, _Stateless): ...


class SolveXyzReference(XyzReferenceCalibration, _Stateless): ...


class SolveTcpZx(TcpZxCalibration, _Stateless): ...


class SolveAbc2Point(Abc2PointCalibration, _Stateless): ...


class SolveAbcWorld(AbcWorldCalibration, _Stateless): ...


class SolveLaserBeam(LaserBeamCalibration, _Stateless): ...


class SolveManual(ManualCalibration, _Stateless): ...


SolveRequest = Annotated[
    SolveXyzNpoint
    | SolveXyzReference
    | SolveTcpZx
    | SolveAbc2Point
    | SolveAbcWorld
    | SolveLaserBeam
    | SolveManual,
    Field(discriminator="method"),
]


# ---- results --------------------------------------------------------------------------------
class QualityOut(BaseModel):
    n_poses: int
    rms_mm: float | None
    max_mm: float | None
    residuals_mm: list[float]
    tcp_sigma_mm: list[float] | None
    tcp_covariance_mm2: list[list[float]] | None = None
    sigma_source: Literal["configured", "residuals"] | None
    orientation_spread_deg: float | None
    condition_number: float | None
    outliers: list[int]
    ellipsoid95_scale: float | None = Field(
        default=None,
        description="multiply the 1-sigma ellipsoid by this for 95 % (F-based when the noise "
        "is estimated from the residuals)",
    )
    orientation_sigma_deg: list[float] | None = None


class CalibrationResult(BaseModel):
    """What a solve produced; the Calibration adds storage fields."""

    method: str
    algorithm: str | None
    status: Literal["accepted", "out_of_tolerance"]
    tcp: Tcp
    reference_point_mm: list[float] | None
    quality: QualityOut
    warnings: list[str]
    orientation_change_deg: float | None = None
    runout_deg: list[float] | None = None
    offset_mm: list[float] | None = None
    tool_length_mm: float | None = None
    widths_mm: list[float] | None = None
    details: dict[str, Any] = Field(default_factory=dict)


class Calibration(CalibrationResult):
    id: str
    tool_id: str
    version: int | None
    active: bool
    created_at: Timestamp
    created_by: str


class CalibrationDetail(Calibration):
    request: dict[str, Any]


class SolveResult(CalibrationResult):
    id: None = None
    version: None = None
    active: bool = False
