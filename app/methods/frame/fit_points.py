"""`fit_points`: the frame that best maps a fixture's nominal points (a drawing, CAD) onto
where they were touched: app.solvers.frame.fit_points' weighted rigid fit (no scale), robust
to one bad touch in five, residuals per touch, a unit or order mix-up answered with the
reading that fits (/convention-mismatch)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field

from app.methods.frame.base import (
    FrameContext,
    FrameMethod,
    FrameSolved,
    FrameTouch,
    NoiseOption,
    TouchedFrameRequest,
    parse_touches,
    solved_from_estimate,
    touch_count,
    touch_noise_of,
    touched_with,
)
from app.schemas.common import Vec3
from app.solvers.frame import fit_points, touch_points
from app.solvers.frame.fit_points import MIN_POINTS
from app.solvers.numbering import number
from app.words import FitPoints


class NominalTouch(FrameTouch):
    """A touch of a point whose coordinates in the frame are known."""

    nominal_mm: Vec3 = Field(description="the touched point's coordinates in the frame (mm)")


class FitPointsCalibration(TouchedFrameRequest):
    method: FitPoints
    touches: Annotated[
        list[NominalTouch],
        touch_count(
            MIN_POINTS,
            hint="touch 3 or more points of the fixture, not on one line, each with its "
            "nominal_mm (5 or more to have one bad touch found)",
        ),
    ]
    options: NoiseOption = Field(default_factory=NoiseOption)


def fiducial_name(index: int) -> str:
    """The name a fit_points touch's fiducial gets: by its number, as a person counts."""
    return f"touch_{number(index)}"


def run(request: FitPointsCalibration, ctx: FrameContext) -> FrameSolved:
    """The rigid fit of the nominal points to the touched ones."""
    pointer = touched_with(request, ctx)
    rotations, positions = parse_touches(ctx, request.format, request.units, request.touches)
    estimate = fit_points(
        np.array([t.nominal_mm for t in request.touches], dtype=float),
        touch_points(rotations, positions, pointer.pointer.tcp_mm),
        rotations,
        pointer.pointer.tcp_covariance_mm2,
        touch_noise_mm=touch_noise_of(request.options.touch_noise_mm, ctx),
    )
    n = len(request.touches)
    return solved_from_estimate(
        estimate,
        names=[fiducial_name(i) for i in range(n)],
        pointer=pointer,
        what=f"{request.method} of {n} touches",
    )


FIT_POINTS_FRAME = FrameMethod(
    request=FitPointsCalibration,
    run=run,
    description="N >= 3 touches of points known in the frame (nominal_mm, from a drawing or "
    "CAD) -> the rigid transform that fits them best, robust to one bad touch in five",
    example_body={
        "tool_id": "pointer",
        "format": "xyz_wxyz",
        "touches": [
            {"nominal_mm": [0.0, 0.0, 0.0], "pose": [1000.0, -200.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
            {"nominal_mm": [500.0, 0.0, 0.0], "pose": [1500.0, -200.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
            {"nominal_mm": [500.0, 300.0, 0.0], "pose": [1500.0, 100.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
            {"nominal_mm": [0.0, 300.0, 0.0], "pose": [1000.0, 100.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
        ],
        "options": {"touch_noise_mm": 0.05},
    },
)
