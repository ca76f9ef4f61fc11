"""`laser_beam`: tool axis, runout, offset and length from two crossed laser beams."""

from __future__ import annotations

from typing import Any

import numpy as np

from app.methods.base import MethodContext, SolvedTcp, orientation_change_deg
from app.schemas.calibrations import LaserBeamCalibration, LaserGeometry, SweepIn
from app.solvers.errors import SolveError
from app.solvers.laser import LaserDevice, Sweep, solve_laser


def device_from(geometry: LaserGeometry, ctx: MethodContext) -> LaserDevice:
    """The beam geometry named by id (stored per robot) or given as numbers."""
    if geometry.device_id is not None:
        a_y, b_x, z = ctx.laser_device(geometry.device_id)
        return LaserDevice(beam_a_y_mm=a_y, beam_b_x_mm=b_x, plane_z_mm=z)
    if geometry.beam_a_y_mm is None or geometry.beam_b_x_mm is None or geometry.plane_z_mm is None:
        raise SolveError(
            "invalid-options", "laser needs device_id or the three beam numbers", loc=("laser",)
        )
    return LaserDevice(
        beam_a_y_mm=geometry.beam_a_y_mm,
        beam_b_x_mm=geometry.beam_b_x_mm,
        plane_z_mm=geometry.plane_z_mm,
    )


def sweeps_from(sweeps: list[SweepIn]) -> list[Sweep]:
    """API sweeps as solver sweeps."""
    return [Sweep(beam=s.beam, break_mm=s.break_mm, restore_mm=s.restore_mm) for s in sweeps]


def run(request: LaserBeamCalibration, ctx: MethodContext) -> SolvedTcp:
    """Solve the laser procedure held at one flange orientation (poses[0])."""
    if len(request.poses) != 1:
        raise SolveError(
            "invalid-pose",
            f"laser_beam takes one pose, the flange pose held during the sweeps (its rotation "
            f"is used); got {len(request.poses)}",
            loc=("poses",),
        )
    rotations, _ = ctx.parse_poses(request.format, request.poses, request.units, loc=("poses",))
    result = solve_laser(
        flange_rotation=rotations[0],
        sweeps=sweeps_from(request.sweeps),
        descent_mm=request.descent_mm,
        device=device_from(request.laser, ctx),
        trigger_noise_mm=request.options.trigger_noise_mm,
    )
    sigma = result.sigma
    with_sigma = sigma.source != "none"
    quality: dict[str, Any] = {
        "n_poses": len(request.sweeps),
        "rms_mm": _rms(result.residuals_mm),
        "max_mm": max(result.residuals_mm, default=0.0),
        "residuals_mm": list(result.residuals_mm),
        "tcp_sigma_mm": list(sigma.tcp_mm) if with_sigma else None,
        "tcp_covariance_mm2": None,
        "sigma_source": sigma.source if with_sigma else None,
        "orientation_spread_deg": None,
        "condition_number": None,
        "outliers": [],
        "orientation_sigma_deg": list(sigma.rotation_deg) if with_sigma else None,
    }
    return SolvedTcp(
        position_mm=result.tcp_mm,
        quaternion=np.asarray(result.quaternion_wxyz),
        algorithm=None,
        quality=quality,
        warnings=list(result.warnings),
        extra={
            "runout_deg": list(result.runout_deg),
            "offset_mm": list(result.offset_mm),
            "tool_length_mm": result.tool_length_mm,
            "widths_mm": list(result.widths_mm),
            "orientation_change_deg": orientation_change_deg(ctx, result.quaternion_wxyz),
            "details": {
                "axis_point_flange_mm": [float(v) for v in result.axis_point_flange_mm],
                "axis_direction_flange": [float(v) for v in result.axis_direction_flange],
                "heights_mm": list(result.heights_mm),
                "sigma": {
                    "runout_deg": list(sigma.runout_deg),
                    "offset_mm": list(sigma.offset_mm),
                    "tool_length_mm": sigma.tool_length_mm,
                    "source": sigma.source,
                },
            },
        },
    )


def _rms(values: tuple[float, ...]) -> float:
    return float(sum(v * v for v in values) / len(values)) ** 0.5 if values else 0.0
