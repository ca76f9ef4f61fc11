"""`laser_beam`: tool axis, runout, offset and length from two crossed laser beams."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import ConfigDict, Field, model_validator

from app.methods.base import (
    Method,
    MethodContext,
    PoseCount,
    PosesRequired,
    Solved,
    orientation_change_deg,
)
from app.schemas.common import (
    FiniteFloat,
    Pose,
    PositiveFloat,
    ResourceId,
    StrictModel,
    Vec3,
    one_of,
)
from app.schemas.references import SweepIn
from app.schemas.results import LaserDetails, LaserSigma, QualityOut, ResultExtras
from app.solvers.laser import LaserDevice, LaserResult, Sweep, solve_laser
from app.words import LaserBeam


class LaserGeometry(StrictModel):
    model_config = ConfigDict(
        json_schema_extra=one_of(
            (("device_id",), ("beam_a_y_mm", "beam_b_x_mm", "plane_z_mm")),
            (("beam_a_y_mm", "beam_b_x_mm", "plane_z_mm"), ("device_id",)),
        )
    )

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


class LaserOptions(StrictModel):
    trigger_noise_mm: PositiveFloat | None = None


class LaserBeamCalibration(PosesRequired):
    method: LaserBeam
    poses: Annotated[
        list[Pose],
        PoseCount(1, 1, hint="the flange pose held during the sweeps (its rotation is used)"),
    ]
    laser: LaserGeometry
    sweeps: Annotated[list[SweepIn], Field(min_length=4, max_length=200)]
    descent_mm: Vec3
    options: LaserOptions = Field(default_factory=LaserOptions)


def device_from(geometry: LaserGeometry, ctx: MethodContext) -> LaserDevice:
    """The beam geometry named by id (stored per robot) or given as numbers."""
    if geometry.device_id is not None:
        a_y, b_x, z = ctx.laser_device(geometry.device_id)
        return LaserDevice(beam_a_y_mm=a_y, beam_b_x_mm=b_x, plane_z_mm=z)
    # the schema guarantees all three numbers when there is no device_id
    assert geometry.beam_a_y_mm is not None
    assert geometry.beam_b_x_mm is not None
    assert geometry.plane_z_mm is not None
    return LaserDevice(
        beam_a_y_mm=geometry.beam_a_y_mm,
        beam_b_x_mm=geometry.beam_b_x_mm,
        plane_z_mm=geometry.plane_z_mm,
    )


def sweeps_from(sweeps: list[SweepIn]) -> list[Sweep]:
    """API sweeps as solver sweeps."""
    return [Sweep(beam=s.beam, break_mm=s.break_mm, restore_mm=s.restore_mm) for s in sweeps]


def _quality(result: LaserResult, n_sweeps: int) -> QualityOut:
    sigma = result.sigma
    with_sigma = sigma.source != "none"
    residuals = list(result.residuals_mm)
    return QualityOut(
        n_poses=n_sweeps,
        rms_mm=float(np.sqrt(np.mean(np.square(residuals)))) if residuals else 0.0,
        max_mm=max(residuals, default=0.0),
        residuals_mm=residuals,
        tcp_sigma_mm=list(sigma.tcp_mm) if with_sigma else None,
        sigma_source=sigma.source if with_sigma else None,
        orientation_spread_deg=None,
        condition_number=None,
        outliers=[],
        orientation_sigma_deg=list(sigma.rotation_deg) if with_sigma else None,
    )


def run(request: LaserBeamCalibration, ctx: MethodContext) -> Solved:
    """Solve the laser procedure held at one flange orientation (poses[0])."""
    rotations, _ = ctx.parse_poses(request.format, request.poses, request.units, loc=("poses",))
    result = solve_laser(
        flange_rotation=rotations[0],
        sweeps=sweeps_from(request.sweeps),
        descent_mm=request.descent_mm,
        device=device_from(request.laser, ctx),
        trigger_noise_mm=request.options.trigger_noise_mm,
    )
    sigma = result.sigma
    return Solved(
        position_mm=result.tcp_mm,
        quaternion=np.asarray(result.quaternion_wxyz),
        quality=_quality(result, len(request.sweeps)),
        warnings=list(result.warnings),
        extras=ResultExtras(
            runout_deg=list(result.runout_deg),
            offset_mm=list(result.offset_mm),
            tool_length_mm=result.tool_length_mm,
            widths_mm=list(result.widths_mm),
            orientation_change_deg=orientation_change_deg(ctx, result.quaternion_wxyz),
            details=LaserDetails(
                axis_point_flange_mm=[float(v) for v in result.axis_point_flange_mm],
                axis_direction_flange=[float(v) for v in result.axis_direction_flange],
                heights_mm=list(result.heights_mm),
                sigma=LaserSigma(
                    runout_deg=list(sigma.runout_deg),
                    offset_mm=list(sigma.offset_mm),
                    tool_length_mm=sigma.tool_length_mm,
                    source=sigma.source,
                ),
            ),
        ),
    )


LASER_BEAM = Method(
    request=LaserBeamCalibration,
    run=run,
    description="beam break/restore sweeps at two or more heights and a final descent -> "
    "tool axis, runout, offset, length",
    example_body={
        "format": "xyz_wxyz",
        "poses": [[420.0, -150.0, 250.0, 0.014599, -0.965781, 0.258623, 0.012945]],
        "laser": {"beam_a_y_mm": -150.0, "beam_b_x_mm": 420.0, "plane_z_mm": 100.0},
        "sweeps": [
            {
                "beam": "a",
                "break_mm": [391.232, -153.342, 200.0],
                "restore_mm": [391.232, -147.342, 200.0],
            },
            {
                "beam": "b",
                "break_mm": [418.232, -180.342, 200.0],
                "restore_mm": [424.232, -180.342, 200.0],
            },
            {
                "beam": "a",
                "break_mm": [391.285, -153.506, 220.0],
                "restore_mm": [391.285, -147.506, 220.0],
            },
            {
                "beam": "b",
                "break_mm": [418.285, -180.506, 220.0],
                "restore_mm": [424.285, -180.506, 220.0],
            },
            {
                "beam": "a",
                "break_mm": [391.337, -153.671, 240.0],
                "restore_mm": [391.337, -147.671, 240.0],
            },
            {
                "beam": "b",
                "break_mm": [418.337, -180.671, 240.0],
                "restore_mm": [424.337, -180.671, 240.0],
            },
        ],
        "descent_mm": [421.364, -150.753, 249.994],
    },
)
