"""`xyz_reference`: one touch of a known point by the new tool (the lecture's second method)."""

from __future__ import annotations

import numpy as np

from app.methods.base import MethodContext, SolvedTcp, StoredPoint
from app.methods.npoint import quality_document
from app.schemas.calibrations import XyzReferenceCalibration
from app.solvers.errors import SolveError
from app.solvers.reference import reference_point_from_touch, solve_reference


def _reference(
    request: XyzReferenceCalibration, ctx: MethodContext, touch_noise: float | None
) -> StoredPoint:
    options = request.options
    if options.reference_point_id is not None:
        return ctx.reference_point(options.reference_point_id)
    if options.reference_point_mm is not None:
        return StoredPoint(np.asarray(options.reference_point_mm, dtype=float), None)
    if options.reference_tool_id is None or options.reference_pose is None:  # schema ensures
        raise SolveError(
            "invalid-options", "give a reference point or a reference tool touch", loc=("options",)
        )
    frame = ctx.tool_frame(options.reference_tool_id)
    rotations, positions = ctx.parse_poses(
        request.format, [options.reference_pose], request.units, loc=("options", "reference_pose")
    )
    point, covariance = reference_point_from_touch(
        tcp_mm=frame.position_mm,
        tcp_covariance_mm2=frame.covariance_mm2,
        rotation=rotations[0],
        position_mm=positions[0],
        touch_noise_mm=touch_noise,
    )
    return StoredPoint(point, covariance)


def run(request: XyzReferenceCalibration, ctx: MethodContext) -> SolvedTcp:
    """t2 = R^T (r - f) with the uncertainty of r and of the touch propagated."""
    if len(request.poses) != 1:
        raise SolveError(
            "invalid-pose",
            f"xyz_reference takes exactly one touch by the new tool, got {len(request.poses)}; "
            "for several touches of one point use xyz_npoint",
            loc=("poses",),
        )
    touch_noise = request.options.touch_noise_mm or ctx.tolerance.get("touch_noise_mm")
    reference = _reference(request, ctx, touch_noise)
    rotations, positions = ctx.parse_poses(
        request.format, request.poses, request.units, loc=("poses",)
    )
    result = solve_reference(
        reference_mm=reference.position_mm,
        reference_covariance_mm2=reference.covariance_mm2,
        rotation=rotations[0],
        position_mm=positions[0],
        touch_noise_mm=touch_noise,
    )
    return SolvedTcp(
        position_mm=result.tcp_mm,
        quaternion=None,
        algorithm=None,
        quality=quality_document(result.quality),
        warnings=list(result.quality.warnings),
        reference_point_mm=[float(v) for v in reference.position_mm],
    )
