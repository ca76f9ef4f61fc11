"""Orientation methods: `tcp_z_x` (translations), `abc_2point` (touches), `abc_world` (alignment).

Each fills tcp.quaternion; position comes from the touches (tcp_z_x) or is the given /
active TCP (abc_*). When the tool had an active orientation, the angle to it is reported.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from app.methods.base import MethodContext, SolvedTcp, empty_quality, orientation_change_deg
from app.methods.npoint import quality_document, solve_touches
from app.schemas.calibrations import (
    Abc2PointCalibration,
    AbcWorldCalibration,
    TcpZxCalibration,
)
from app.solvers.errors import SolveError
from app.solvers.orientation import (
    Direction,
    OrientationResult,
    orientation_from_touches,
    orientation_from_translations,
    orientation_from_world,
)


def _known_tcp(tcp_mm: list[float] | None, ctx: MethodContext) -> NDArray[np.float64]:
    if tcp_mm is not None:
        return np.asarray(tcp_mm, dtype=float)
    frame = ctx.active_frame()
    if frame is None:
        raise SolveError(
            "invalid-options",
            "this method needs the TCP position: give options.tcp_mm, or calibrate the "
            "position first (xyz_npoint) so the tool has an active TCP",
            loc=("options", "tcp_mm"),
        )
    return frame.position_mm


def _with_orientation(
    solved: SolvedTcp,
    result: OrientationResult,
    ctx: MethodContext,
) -> SolvedTcp:
    solved.quaternion = np.asarray(result.quaternion_wxyz)
    solved.quality["orientation_sigma_deg"] = (
        list(result.sigma_deg) if result.sigma_source != "none" else None
    )
    solved.warnings += list(result.warnings)
    solved.extra["orientation_change_deg"] = orientation_change_deg(ctx, result.quaternion_wxyz)
    return solved


def run_tcp_z_x(request: TcpZxCalibration, ctx: MethodContext) -> SolvedTcp:
    """Position from the N-point touches, frame from pure translations along tool Z (and X)."""
    touches = solve_touches(ctx, request.format, request.poses, request.units, request.options)
    directions = []
    for i, d in enumerate(request.directions):
        rotations, positions = ctx.parse_poses(
            request.format, [d.from_, d.to], request.units, loc=("directions", i)
        )
        directions.append(
            Direction(
                axis=d.axis,
                rotation_from=rotations[0],
                position_from_mm=positions[0],
                rotation_to=rotations[1],
                position_to_mm=positions[1],
            )
        )
    noise = request.options.touch_noise_mm or ctx.tolerance.get("touch_noise_mm")
    result = orientation_from_translations(directions, position_noise_mm=noise)
    solved = SolvedTcp(
        position_mm=touches.tcp_mm,
        quaternion=None,
        algorithm=touches.algorithm,
        quality=quality_document(touches.quality),
        warnings=list(touches.quality.warnings),
        reference_point_mm=[float(v) for v in touches.pivot_mm],
        reference_covariance_mm2=[[float(v) for v in r] for r in touches.pivot_covariance_mm2],
    )
    return _with_orientation(solved, result, ctx)


def run_abc_2point(request: Abc2PointCalibration, ctx: MethodContext) -> SolvedTcp:
    """Orientation from three touches of one point (KUKA ABC 2-point); position unchanged."""
    if len(request.poses) != 3:
        raise SolveError(
            "invalid-pose",
            f"abc_2point takes exactly 3 touches (TCP, a point on the working axis behind it, "
            f"a point on +Y), got {len(request.poses)}",
            loc=("poses",),
        )
    tcp = _known_tcp(request.options.tcp_mm, ctx)
    rotations, positions = ctx.parse_poses(
        request.format, request.poses, request.units, loc=("poses",)
    )
    noise = request.options.touch_noise_mm or ctx.tolerance.get("touch_noise_mm")
    result = orientation_from_touches(
        tcp_mm=tcp,
        rotations=rotations,
        positions_mm=positions,
        working_axis=request.options.working_axis,
        touch_noise_mm=noise,
    )
    solved = SolvedTcp(
        position_mm=tcp, quaternion=None, algorithm=None, quality=empty_quality(3), graded=False
    )
    return _with_orientation(solved, result, ctx)


def run_abc_world(request: AbcWorldCalibration, ctx: MethodContext) -> SolvedTcp:
    """Orientation from one pose aligned to base axes (KUKA ABC world 5D/6D)."""
    if len(request.poses) != 1:
        raise SolveError(
            "invalid-pose",
            f"abc_world takes exactly one aligned pose, got {len(request.poses)}",
            loc=("poses",),
        )
    tcp = _known_tcp(request.options.tcp_mm, ctx)
    rotations, _ = ctx.parse_poses(request.format, request.poses, request.units, loc=("poses",))
    result = orientation_from_world(
        rotation=rotations[0],
        align={str(k): str(v) for k, v in request.options.align.items()},
        working_axis=request.options.working_axis,
    )
    solved = SolvedTcp(
        position_mm=tcp, quaternion=None, algorithm=None, quality=empty_quality(1), graded=False
    )
    return _with_orientation(solved, result, ctx)
