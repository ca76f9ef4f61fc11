"""A frame's tolerance: when a frame calibration counts as good enough to activate, and the
limits of a re-check after a move (API.md v1.4 "Frames", "After a move").

A module of its own so that the frame resource (app.schemas for the Frame document, the
services that store it) and the frame methods (app.methods.frame, which read the touch noise
and hand the rest on) import the one schema without importing each other.
"""

from __future__ import annotations

from pydantic import Field

from app.schemas.common import PositiveFloat, StrictModel, TouchNoise


class FrameTolerance(StrictModel):
    """When a frame calibration is accepted, and how far a re-check may correct it."""

    max_rms_mm: PositiveFloat = Field(
        default=0.5, description="rms of the touches' residuals (fit_points, fixed_npoint)"
    )
    max_residual_mm: PositiveFloat = Field(default=1.0, description="largest residual of one touch")
    touch_noise_mm: TouchNoise | None = Field(
        default=None,
        description="1-sigma per axis of a touch (mm): the uncertainty a calibration reports "
        "propagates it; unset, it is estimated from the residuals when there are spare touches "
        "(three_point and four_point have none: they need it set here or in the options)",
    )
    check_mm: PositiveFloat = Field(
        default=1.0,
        description="a re-check whose largest fiducial deviation exceeds this corrects the "
        "frame (or says it needs recalibrating)",
    )
    max_change_mm: PositiveFloat = Field(
        default=5.0,
        description="a calibration whose frame moves a fiducial further than this from the "
        'active frame is stored but not activated by "auto"',
    )
    max_correction_mm: PositiveFloat = Field(
        default=2.0,
        description="a re-check corrects the frame when its largest deviation exceeds check_mm "
        "and stays within this; beyond it nothing changes and the frame needs recalibrating",
    )
