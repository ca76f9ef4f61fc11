"""`xyz_npoint`: N touches of one fixed point -> TCP position and the point itself."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated

import numpy as np
from pydantic import Field

from app.errors import InvalidInput
from app.methods.base import (
    Method,
    MethodContext,
    PoseCount,
    PosesRequired,
    Solved,
    StoredPoint,
    touch_noise,
)
from app.schemas.common import (
    Name,
    NonNegativeFloat,
    Pose,
    StrictModel,
    TouchNoise,
    Units,
)
from app.schemas.results import QualityOut
from app.solvers.npoint import MIN_POSES, NPointResult, solve_npoint
from app.solvers.quality import format_vector
from app.words import Algorithm, PoseFormat, XyzNpoint

#: N touches of one fixed point, each from another orientation.
Touches = Annotated[
    list[Pose],
    PoseCount(MIN_POSES, hint="touch one fixed point from 4 or more different orientations"),
]


class NPointOptions(StrictModel):
    algorithm: Algorithm = "robust"
    touch_noise_mm: TouchNoise | None = None
    orientation_noise_deg: NonNegativeFloat | None = None
    save_reference_point: Name | None = None


class XyzNpointCalibration(PosesRequired):
    method: XyzNpoint
    poses: Touches
    options: NPointOptions = Field(default_factory=NPointOptions)


def solve_touches(
    ctx: MethodContext,
    fmt: PoseFormat,
    poses: Sequence[Pose],
    units: Units | None,
    options: NPointOptions,
) -> NPointResult:
    """Parse the touches and run the chosen estimator with the tool's noise and tolerance."""
    rotations, positions = ctx.parse_poses(fmt, poses, units, loc=("poses",))
    limit = ctx.tolerance.max_rms_mm
    noise = touch_noise(options.touch_noise_mm, ctx)
    # With a configured noise the solver refuses, before anything else, a pose set whose
    # geometry cannot reach the tolerance (its predicted TCP 1-sigma exceeds max_rms_mm).
    result = solve_npoint(
        rotations,
        positions,
        algorithm=options.algorithm,
        touch_noise_mm=noise,
        orientation_noise_deg=options.orientation_noise_deg,
        max_tcp_sigma_mm=limit if noise is not None else None,
    )
    if noise is None:
        _refuse_weak_geometry(result, limit)
    return result


def _refuse_weak_geometry(result: NPointResult, limit: float) -> None:
    """With the noise estimated from the residuals, blame the spread only when the touches
    themselves are within tolerance: then the geometry, not the touching, is what fails.
    Noisy touches with a good spread are graded out_of_tolerance instead."""
    quality = result.quality
    if quality.rms_mm > limit:
        return
    evals, evecs = np.linalg.eigh(np.asarray(quality.tcp_covariance_mm2))
    worst = float(np.sqrt(max(float(evals[-1]), 0.0)))
    if worst <= limit:
        return
    direction = evecs[:, -1] * (1.0 if evecs[np.argmax(np.abs(evecs[:, -1])), -1] > 0 else -1.0)
    raise InvalidInput(
        "insufficient-spread",
        f"the touches agree to {quality.rms_mm:.3g} mm rms, but their orientations are so "
        f"alike that the TCP is only determined to {worst:.3g} mm (1 sigma) along the flange "
        f"direction {format_vector(direction)}, more than the tool's max_rms_mm {limit:g} mm: "
        "touch from orientations further apart (tilt the tool more, about different axes)",
        loc=("poses",),
        context={
            "predicted_sigma_mm": worst,
            "max_tcp_sigma_mm": limit,
            "direction_flange": [float(x) for x in direction],
        },
    )


def solved_from_touches(result: NPointResult) -> Solved:
    """The TCP position of an N-point fit; the touched point becomes the reference point."""
    return Solved(
        position_mm=result.tcp_mm,
        quaternion=None,
        quality=QualityOut.from_solver(result.quality),
        algorithm=result.algorithm,
        warnings=list(result.quality.warnings),
        reference_point=StoredPoint(
            np.asarray(result.pivot_mm, dtype=float),
            np.asarray(result.pivot_covariance_mm2, dtype=float),
        ),
    )


def run(request: XyzNpointCalibration, ctx: MethodContext) -> Solved:
    """TCP position from N touches; the touched point becomes `reference_point_mm`."""
    return solved_from_touches(
        solve_touches(ctx, request.format, request.poses, request.units, request.options)
    )


XYZ_NPOINT = Method(
    request=XyzNpointCalibration,
    run=run,
    description="N >= 4 touches of one fixed point from different orientations -> TCP "
    "position and the touched point (the XYZ 4-point method, generalised)",
    example_body={
        "format": "kuka_abc",
        "poses": [
            [753.897, -81.965, 320.965, -108.243, -25.048, -167.066],
            [726.441, -182.084, 364.264, -43.964, -1.541, 178.498],
            [769.644, -132.861, 362.962, -173.468, 24.67, -168.342],
            [765.433, -235.479, 370.082, 101.353, 4.856, 153.693],
            [794.554, -232.496, 372.164, 121.53, 4.518, 160.09],
            [767.49, -192.016, 376.066, -41.68, 12.681, 169.542],
        ],
        "note": "after torch change",
    },
)
