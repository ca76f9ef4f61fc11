"""`three_point`: a frame from three role touches, as each maker's pendant computes it.

Roles origin, x (a point on +X), xy (a point in the XY plane on the +Y side) by default;
`options.convention` names another maker's teaching order where its documents differ. The
constructions, and the vendor documents each is cited from, are
app.solvers.frame.construction's (THREE_POINT, one entry a convention): the common
origin/+X/XY teach, the user method (X1, X2, Y1; RAPID DefFrame with Origin 3), and the
plane feature taught by three points.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from app.methods.frame.base import FrameContext, FrameMethod, FrameSolved, RoleSet, touch_count
from app.methods.frame.roles import RoleOptions, RoleRequest, RoleTouch, solve_roles
from app.solvers.frame import THREE_POINT
from app.words import ThreePoint, ThreePointConvention


class ThreePointOptions(RoleOptions):
    convention: ThreePointConvention = Field(
        default="origin_x_xy",
        description="whose three-point teach: the default's roles are origin, x, xy; GET "
        "/v1/methods lists each convention's roles and what each role touches",
    )


class ThreePointCalibration(RoleRequest):
    method: ThreePoint
    touches: Annotated[
        list[RoleTouch],
        touch_count(3, 3, hint="one touch per role of the convention, each role once"),
    ]
    options: ThreePointOptions = Field(default_factory=ThreePointOptions)


def run(request: ThreePointCalibration, ctx: FrameContext) -> FrameSolved:
    """The frame through the three role touches, by the convention's construction."""
    convention = request.options.convention
    return solve_roles(request, ctx, THREE_POINT[convention], f"{request.method} ({convention})")


THREE_POINT_FRAME = FrameMethod(
    request=ThreePointCalibration,
    run=run,
    description="three touches: the origin, a point on +X, a point in the XY plane on the +Y "
    "side (options.convention for the user method's X1, X2, Y1 or the plane feature)",
    example_body={
        "tool_id": "pointer",
        "format": "xyz_wxyz",
        "touches": [
            {"role": "origin", "pose": [1000.0, -200.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
            {"role": "x", "pose": [1400.0, -200.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
            {"role": "xy", "pose": [1100.0, 100.0, 580.0, 0.0, 1.0, 0.0, 0.0]},
        ],
        "options": {"touch_noise_mm": 0.05},
    },
    roles=tuple(
        RoleSet(convention=name, words=dict(construction.words))
        for name, construction in THREE_POINT.items()
    ),
)
