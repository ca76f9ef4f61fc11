"""What a calibration produces: the one `CalibrationResult` that is stored and served."""

from __future__ import annotations

from pydantic import BaseModel, Field

from app.schemas.common import StoredWord, StrictModel, Timestamp
from app.schemas.tools import Tcp
from app.solvers.orientation import SigmaEstimate
from app.solvers.quality import Quality, SigmaSource
from app.words import Algorithm, MethodName, Status, TouchOrigin


class QualityOut(BaseModel):
    n_poses: int
    rms_mm: float | None
    max_mm: float | None
    residuals_mm: list[float]
    tcp_sigma_mm: list[float] | None
    tcp_covariance_mm2: list[list[float]] | None = None
    sigma_source: SigmaSource | None
    orientation_spread_deg: float | None
    condition_number: float | None
    outliers: list[int]
    ellipsoid95_scale: float | None = Field(
        default=None,
        description="multiply the 1-sigma ellipsoid by this for 95 % (F-based when the noise "
        "is estimated from the residuals)",
    )
    orientation_sigma_deg: list[float] | None = None

    @classmethod
    def from_solver(cls, quality: Quality) -> QualityOut:
        """A solver's Quality (its warnings travel separately)."""
        return cls(
            n_poses=quality.n_poses,
            rms_mm=quality.rms_mm,
            max_mm=quality.max_mm,
            residuals_mm=list(quality.residuals_mm),
            tcp_sigma_mm=list(quality.tcp_sigma_mm),
            tcp_covariance_mm2=[list(row) for row in quality.tcp_covariance_mm2],
            sigma_source=quality.sigma_source,
            orientation_spread_deg=quality.orientation_spread_deg,
            condition_number=quality.condition_number,
            outliers=list(quality.outliers),
            ellipsoid95_scale=quality.ellipsoid95_scale,
        )

    @classmethod
    def ungraded(cls, n_poses: int) -> QualityOut:
        """Quality of a result with no redundancy to measure (numbers entered by hand)."""
        return cls(
            n_poses=n_poses,
            rms_mm=None,
            max_mm=None,
            residuals_mm=[],
            tcp_sigma_mm=None,
            sigma_source=None,
            orientation_spread_deg=None,
            condition_number=None,
            outliers=[],
        )


class LaserSigma(BaseModel):
    runout_deg: list[float]
    offset_mm: list[float]
    tool_length_mm: float
    source: StoredWord[SigmaEstimate]


class LaserDetails(BaseModel):
    """The laser method's intermediate geometry, for a report."""

    axis_point_flange_mm: list[float]
    axis_direction_flange: list[float]
    heights_mm: list[float]
    sigma: LaserSigma


class PlaneOut(BaseModel):
    """One plane an `xyz_plane` calibration touched, estimated with the TCP."""

    label: str = Field(description="the plane's label: a, b or c")
    normal: list[float] = Field(description="unit normal, robot base frame")
    offset_mm: float = Field(description="d in n . x = d (mm, base frame): the plane's distance")
    normal_sigma_deg: float = Field(description="1-sigma of the normal's direction (deg)")
    offset_sigma_mm: float = Field(description="1-sigma of the offset (mm)")
    n_touches: int = Field(description="how many touches touched this plane")


class PlaneDetails(BaseModel):
    """The plane method's planes and the TCP's uncertainty along the tool's own axes."""

    planes: list[PlaneOut] = Field(description="each plane touched, in label order")
    touch_planes: list[str] = Field(description="the plane each touch touched, in pose order")
    tcp_sigma_tool_mm: list[float] | None = Field(
        description="the TCP's 1-sigma along the x, y, z axes of the tool frame (the result's "
        "orientation; z is the tool axis, usually the least certain: it is told from the "
        "plane's offset only by how much the tilts differ)"
    )
    touch_noise_mm: float = Field(
        description="the touch noise behind the uncertainty (configured, or estimated from the "
        "distances to the plane)"
    )


class NoDetails(StrictModel):
    """Methods without intermediate figures report `details: {}`."""


class ResultExtras(BaseModel):
    """Figures only some methods report (orientation methods, the laser and plane methods)."""

    orientation_change_deg: float | None = Field(
        default=None, description="angle to the previously active orientation"
    )
    runout_deg: list[float] | None = None
    offset_mm: list[float] | None = None
    tool_length_mm: float | None = None
    widths_mm: list[float] | None = None
    details: LaserDetails | PlaneDetails | NoDetails = Field(default_factory=NoDetails)


class CalibrationResult(ResultExtras):
    """What a solve produced; a stored Calibration adds its storage fields."""

    method: StoredWord[MethodName]
    algorithm: StoredWord[Algorithm] | None
    status: Status
    tcp: Tcp
    reference_point_mm: list[float] | None
    quality: QualityOut
    warnings: list[str]
    change_from_active_mm: float | None = Field(
        default=None,
        description="distance (mm) from the active version's TCP position; null when the tool "
        "had no active version",
    )
    summary: str = Field(
        default="", description="the verdict in one sentence, what to do next included"
    )


class Calibration(CalibrationResult):
    id: str
    tool_id: str
    version: int | None
    active: bool
    created_at: Timestamp
    created_by: str


class TouchGeometry(BaseModel):
    """Where the touches were, for a report's 3-D view (methods that take poses)."""

    flange_positions_mm: list[list[float]] = Field(
        description="each pose's flange position in the base frame, in submission order"
    )
    tip_positions_mm: list[list[float]] = Field(
        description="where the calibrated TCP was at each pose (flange pose applied to the TCP)"
    )
    ellipsoid95_semi_axes_mm: list[float] | None = Field(
        default=None, description="the TCP's 95 % uncertainty ellipsoid's semi-axes, longest first"
    )
    ellipsoid95_axes: list[list[float]] | None = Field(
        default=None, description="the unit direction (flange frame) of each semi-axis"
    )


class TouchSource(BaseModel):
    index: int = Field(description="the touch's index in poses, from 0")
    source: TouchOrigin = Field(
        description="typed by a person, or read from the robot's controller"
    )
    read_at: Timestamp | None = Field(description="when the controller was read; null if typed")
    readings: dict[str, str] | None = Field(
        default=None, description="what the controller printed, as read; null if typed"
    )


class CalibrationDetail(Calibration):
    request: dict[str, object] = Field(description="the submission exactly as received")
    geometry: TouchGeometry | None = Field(
        default=None, description="the touches in space; null for numbers entered by hand"
    )
    touches: list[TouchSource] | None = Field(
        default=None,
        description="where each pose came from (typed, or read from the controller with "
        "what it printed), for a calibration a guided session finished; else null",
    )


class SolveResult(CalibrationResult):
    id: None = None
    version: None = None
    active: bool = False
