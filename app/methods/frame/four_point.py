"""`four_point`: the X axis and the XY plane from three touches, the origin from a fourth
apart from them (app.solvers.frame.construction's FOUR_POINT, the four point user frame:
orient origin point, X direction point, Y direction point, system origin)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from app.methods.frame.base import FrameContext, FrameMethod, FrameSolved, RoleSet, touch_count
from app.methods.frame.roles import RoleOptions, RoleRequest, RoleTouch, role_hint, solve_roles
from app.solvers.frame import FOUR_POINT
from app.words import FourPoint


class FourPointCalibration(RoleRequest):
    method: FourPoint
    touches: Annotated[list[RoleTouch], touch_count(4, 4, hint=role_hint(FOUR_POINT))]
    options: RoleOptions = Field(default_factory=RoleOptions)


def run(request: FourPointCalibration, ctx: FrameContext) -> FrameSolved:
    """The frame of the four role touches."""
    return solve_roles(request, ctx, FOUR_POINT, request.method)


FOUR_POINT_FRAME = FrameMethod(
    request=FourPointCalibration,
    run=run,
    description="four touches: the start of the X axis, a point farther along +X, a point in "
    "the XY plane on the +Y side, and the origin apart from them",
    example_body={
        "tool_id": "pointer",
        "format": "xyz_wxyz",
        "touches": [
            {"role": "x_start", "pose": [950.0, -180.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
            {"role": "x", "pose": [1350.0, -180.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
            {"role": "xy", "pose": [1100.0, 100.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
            {"role": "origin", "pose": [1000.0, -200.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
        ],
        "options": {"touch_noise_mm": 0.05},
    },
    roles=(RoleSet(convention=None, words=dict(FOUR_POINT.words)),),
)
