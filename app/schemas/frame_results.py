"""What a frame calibration method reports (API.md v1.4 "Frame touches and methods"): the
frame, its quality, the pointer it was touched with and the fiducials it keeps.

The FrameCalibration document (its id, version, activation, timestamps) is the frame
resource's and embeds these; app.methods.frame builds them.
"""

from __future__ import annotations

from pydantic import BaseModel, Field

from app.solvers.quality import SigmaSource


class FrameValue(BaseModel):
    """A frame in the robot's base (world) frame; for a fixed tool, the stationary TCP."""

    position_mm: list[float] = Field(description="origin (mm, base frame)")
    quaternion: list[float] = Field(description="unit quaternion [w, x, y, z], frame -> base")


class FrameQuality(BaseModel):
    """How well the touches determine the frame."""

    n_touches: int = Field(description="how many touches the calibration was given")
    rms_mm: float | None = Field(
        description="rms of the residuals of the touches used (0 for an exact construction)"
    )
    max_mm: float | None = Field(description="largest residual of a touch used")
    residuals_mm: list[float] = Field(description="each touch's residual (mm), in touch order")
    position_sigma_mm: list[float] | None = Field(
        description="1-sigma of the origin along the base x, y, z axes (mm)"
    )
    angle_sigma_deg: list[float] | None = Field(
        description="1-sigma of the small rotations about the frame's own x, y, z axes (deg)"
    )
    sigma_source: SigmaSource | None = Field(
        description="where the touch noise behind the sigmas came from: configured, or "
        "estimated from the residuals"
    )
    interval95_scale: float | None = Field(
        description="multiply a 1-sigma by this for a 95 % interval (1.96 with a configured "
        "noise; Student's t with the noise estimated)"
    )
    outliers: list[int] = Field(description="0-based indexes of the touches set aside")


class FramePointer(BaseModel):
    """The pointer tool the touches were made with."""

    tool_id: str
    version: int | None = Field(
        description="the pointer's TCP version used (null: none used, the fixed_npoint fit "
        "found the TCP itself)"
    )
    tcp_sigma_mm: list[float] | None = Field(
        description="1-sigma of the pointer's TCP per flange axis (mm), propagated into the "
        "frame's uncertainty as an error common to every touch"
    )
    tcp_found_mm: list[float] | None = Field(
        default=None, description="fixed_npoint: the pointer's TCP the pivot fit found (mm)"
    )
    tcp_found_sigma_mm: list[float] | None = Field(
        default=None, description="fixed_npoint: 1-sigma of the TCP found per flange axis (mm)"
    )
    distance_from_active_mm: float | None = Field(
        default=None,
        description="fixed_npoint: the TCP found's distance from the pointer's active TCP "
        "(null: the pointer has no active version)",
    )


class Fiducial(BaseModel):
    """A touched point kept with the calibration, in the new frame's coordinates, to be
    touched again after a move."""

    name: str
    nominal_mm: list[float] = Field(description="the point in the frame (mm)")
