"""`xyz_npoint`: N touches of one fixed point -> TCP position and the point itself."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from app.methods.base import MethodContext, SolvedTcp
from app.schemas.calibrations import NPointOptions, XyzNpointCalibration
from app.schemas.common import Units
from app.solvers.errors import SolveError
from app.solvers.npoint import NPointResult, solve_npoint
from app.solvers.quality import Quality, format_vector


def quality_document(quality: Quality) -> dict[str, Any]:
    """A solver's Quality as the API's quality object (warnings travel separately)."""
    doc = dataclasses.asdict(quality)
    doc.pop("warnings")
    return doc


def solve_touches(
    ctx: MethodContext, fmt: str, poses: list[Any], units: Units | None, options: NPointOptions
) -> NPointResult:
    """Parse the touches and run the chosen estimator with the tool's noise and tolerance."""
    rotations, positions = ctx.parse_poses(fmt, poses, units, loc=("poses",))
    tolerance = ctx.tolerance
    limit = float(tolerance["max_rms_mm"])
    touch_noise = options.touch_noise_mm or tolerance.get("touch_noise_mm")
    # With a configured noise the solver refuses, before anything else, a pose set whose
    # geometry cannot reach the tolerance (its predicted TCP 1-sigma exceeds max_rms_mm).
    result = solve_npoint(
        rotations,
        positions,
        algorithm=options.algorithm,
        touch_noise_mm=touch_noise,
        orientation_noise_deg=options.orientation_noise_deg,
        max_tcp_sigma_mm=limit if touch_noise is not None else None,
    )
    if touch_noise is None:
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
    raise SolveError(
        "insufficient-spread",
        f"the touches agree to {quality.rms_mm:.3g} mm rms, but their orientations are so "
        f"alike that the TCP is only determined to {worst:.3g} mm (1 sigma) along the flange "
        f"direction {format_vector(direction)}, more than the tool's max_rms_mm {limit:g} mm: "
        "touch from orientations further apart (tilt the tool more, about different axes)",
        loc=("poses",),
        extra={
            "predicted_sigma_mm": worst,
            "max_tcp_sigma_mm": limit,
            "direction_flange": [float(x) for x in direction],
        },
    )


def run(request: XyzNpointCalibration, ctx: MethodContext) -> SolvedTcp:
    """TCP position from N touches; the touched point becomes `reference_point_mm`."""
    result = solve_touches(ctx, request.format, request.poses, request.units, request.options)
    return SolvedTcp(
        position_mm=result.tcp_mm,
        quaternion=None,
        algorithm=result.algorithm,
        quality=quality_document(result.quality),
        warnings=list(result.quality.warnings),
        reference_point_mm=[float(v) for v in result.pivot_mm],
        reference_covariance_mm2=[[float(v) for v in row] for row in result.pivot_covariance_mm2],
    )
