"""Orientation methods: `tcp_z_x` (translations), `abc_2point` (touches), `abc_world` (alignment).

Each fills tcp.quaternion; position comes from the touches (tcp_z_x) or is the given /
active TCP (abc_*). When the tool had an active orientation, the angle to it is reported.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import ConfigDict, Field

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.methods.base import (
    Method,
    MethodContext,
    PoseCount,
    PosesRequired,
    Solved,
    orientation_change_deg,
    touch_noise,
)
from app.methods.npoint import NPointOptions, Touches, solve_touches, solved_from_touches
from app.schemas.common import Pose, StrictModel, TouchNoise, Vec3
from app.schemas.results import QualityOut
from app.solvers.orientation import (
    AxisDirection,
    Direction,
    OrientationResult,
    orientation_from_touches,
    orientation_from_translations,
    orientation_from_world,
)
from app.vendors.registry import taught_as
from app.words import Abc2Point, AbcWorld, TcpZX, WorkingAxis, word

#: A tool axis an alignment names (the keys of `align`).
ToolAxis = Literal["x", "y", "z"]
#: A base axis with its sign, which a tool axis is aligned with (the values of `align`).
SignedAxis = Literal["+x", "-x", "+y", "-y", "+z", "-z"]


# ---- requests -------------------------------------------------------------------------------
class DirectionIn(StrictModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    axis: AxisDirection
    from_: Pose = Field(alias="from")
    to: Pose


class TcpZxCalibration(PosesRequired):
    method: TcpZX
    poses: Touches
    directions: Annotated[list[DirectionIn], Field(min_length=1, max_length=4)]
    options: NPointOptions = Field(default_factory=NPointOptions)


class Abc2PointOptions(StrictModel):
    working_axis: WorkingAxis = "x"
    tcp_mm: Vec3 | None = None
    touch_noise_mm: TouchNoise | None = None


class Abc2PointCalibration(PosesRequired):
    method: Abc2Point
    poses: Annotated[
        list[Pose],
        PoseCount(3, 3, hint="the TCP touch, a point on the working axis behind it, a point on +Y"),
    ]
    options: Abc2PointOptions = Field(default_factory=Abc2PointOptions)


class AbcWorldOptions(StrictModel):
    align: dict[ToolAxis, SignedAxis] = Field(
        description='tool axis -> base axis, e.g. {"x": "-z"} (5D) or {"x": "-z", "y": "+y"}',
        min_length=1,
        max_length=2,
    )
    working_axis: WorkingAxis = "x"
    tcp_mm: Vec3 | None = None


class AbcWorldCalibration(PosesRequired):
    method: AbcWorld
    poses: Annotated[
        list[Pose], PoseCount(1, 1, hint="one pose with the tool aligned to base axes")
    ]
    options: AbcWorldOptions


# ---- runners --------------------------------------------------------------------------------
def _known_tcp(tcp_mm: list[float] | None, ctx: MethodContext) -> FloatArray:
    if tcp_mm is not None:
        return np.asarray(tcp_mm, dtype=float)
    frame = ctx.active_frame()
    if frame is None:
        raise InvalidInput(
            "invalid-options",
            "this method needs the TCP position: give options.tcp_mm, or calibrate the "
            "position first (xyz_npoint) so the tool has an active TCP",
            loc=("options", "tcp_mm"),
        )
    return frame.position_mm


def _with_orientation(solved: Solved, result: OrientationResult, ctx: MethodContext) -> Solved:
    solved.quaternion = np.asarray(result.quaternion_wxyz)
    solved.quality.orientation_sigma_deg = (
        list(result.sigma_deg) if result.sigma_source != "none" else None
    )
    solved.warnings += list(result.warnings)
    solved.extras.orientation_change_deg = orientation_change_deg(ctx, result.quaternion_wxyz)
    return solved


def _given_position(tcp: FloatArray, n_poses: int) -> Solved:
    """An orientation-only result: the position is the given one, nothing to grade."""
    return Solved(
        position_mm=tcp, quaternion=None, quality=QualityOut.ungraded(n_poses), graded=False
    )


def run_tcp_z_x(request: TcpZxCalibration, ctx: MethodContext) -> Solved:
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
    noise = touch_noise(request.options.touch_noise_mm, ctx)
    result = orientation_from_translations(directions, position_noise_mm=noise)
    return _with_orientation(solved_from_touches(touches), result, ctx)


def run_abc_2point(request: Abc2PointCalibration, ctx: MethodContext) -> Solved:
    """Orientation from three touches of one point; position unchanged."""
    tcp = _known_tcp(request.options.tcp_mm, ctx)
    rotations, positions = ctx.parse_poses(
        request.format, request.poses, request.units, loc=("poses",)
    )
    result = orientation_from_touches(
        tcp_mm=tcp,
        rotations=rotations,
        positions_mm=positions,
        working_axis=request.options.working_axis,
        touch_noise_mm=touch_noise(request.options.touch_noise_mm, ctx),
    )
    return _with_orientation(_given_position(tcp, 3), result, ctx)


def run_abc_world(request: AbcWorldCalibration, ctx: MethodContext) -> Solved:
    """Orientation from one pose aligned to base axes."""
    tcp = _known_tcp(request.options.tcp_mm, ctx)
    rotations, _ = ctx.parse_poses(request.format, request.poses, request.units, loc=("poses",))
    result = orientation_from_world(
        rotation=rotations[0],
        align={str(k): str(v) for k, v in request.options.align.items()},
        working_axis=request.options.working_axis,
    )
    return _with_orientation(_given_position(tcp, 1), result, ctx)


TCP_Z_X = Method(
    request=TcpZxCalibration,
    run=run_tcp_z_x,
    description="N-point touches plus pure translations along tool +-Z (and X) -> full "
    f"frame ({taught_as(word(TcpZX))})",
    example_body={
        "format": "kuka_abc",
        "poses": [
            [791.988, -94.321, 330.308, -171.92, 4.509, 162.959],
            [808.758, -95.827, 330.533, -153.106, -5.058, 159.248],
            [808.147, -18.577, 289.107, 161.295, 18.239, -165.445],
            [695.577, -94.48, 287.304, -96.25, -5.861, -163.662],
            [816.714, -124.35, 332.689, 123.336, -0.248, 156.449],
        ],
        "directions": [
            {
                "axis": "+z",
                "from": [500.0, 100.0, 300.0, -10.423, -4.035, -174.194],
                "to": [549.053, 90.977, 303.519, -10.423, -4.035, -174.194],
            },
            {
                "axis": "+x",
                "from": [505.0, 105.0, 305.0, -10.423, -4.035, -174.194],
                "to": [500.642, 100.659, 354.62, -10.423, -4.035, -174.194],
            },
        ],
    },
)
ABC_2POINT = Method(
    request=Abc2PointCalibration,
    run=run_abc_2point,
    description="TCP touch, a point behind it on the working axis, a point on +Y -> "
    f"orientation ({taught_as(word(Abc2Point))})",
    example_body={
        "format": "kuka_abc",
        "poses": [
            [599.743, -50.246, 300.0, 0.397, -0.082, -179.922],
            [614.686, -19.671, 357.623, 16.084, 5.412, 174.003],
            [599.837, -9.899, 309.979, -0.027, -0.055, 179.969],
        ],
        "options": {"tcp_mm": [0.0, 0.0, 180.0]},
    },
)
ABC_WORLD = Method(
    request=AbcWorldCalibration,
    run=run_abc_world,
    description="one pose with the tool aligned to base axes -> orientation "
    f"({taught_as(word(AbcWorld))})",
    example_body={
        "format": "kuka_abc",
        "poses": [[400.0, 0.0, 300.0, -16.102, 25.659, -23.69]],
        "options": {"align": {"x": "-z", "y": "+y"}, "tcp_mm": [0.0, 0.0, 200.0]},
    },
)
