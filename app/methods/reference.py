"""`xyz_reference`: one touch of a known point by the new tool -> TCP position."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import ConfigDict, model_validator

from app.kinematics.poses import one_pose
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
    Pose,
    ResourceId,
    StrictModel,
    TouchNoise,
    Vec3,
    one_of,
)
from app.schemas.results import QualityOut
from app.solvers.reference import reference_point_from_touch, solve_reference
from app.words import XyzReference

_TOUCHED = ("reference_tool_id", "reference_pose")


class ReferenceOptions(StrictModel):
    model_config = ConfigDict(
        json_schema_extra=one_of(
            (
                ("reference_point_id",),
                ("reference_tool_id", "reference_pose", "reference_point_mm"),
            ),
            (("reference_tool_id", "reference_pose"), ("reference_point_id", "reference_point_mm")),
            (
                ("reference_point_mm",),
                ("reference_point_id", "reference_tool_id", "reference_pose"),
            ),
        )
    )

    reference_point_id: ResourceId | None = None
    reference_tool_id: ResourceId | None = None
    reference_pose: Pose | None = None
    reference_point_mm: Vec3 | None = None
    touch_noise_mm: TouchNoise | None = None

    @model_validator(mode="after")
    def _one_source(self) -> ReferenceOptions:
        sources = [
            self.reference_point_id is not None,
            self.reference_tool_id is not None or self.reference_pose is not None,
            self.reference_point_mm is not None,
        ]
        if sum(sources) != 1:
            raise ValueError(
                "give exactly one of reference_point_id, reference_tool_id + reference_pose, "
                "or reference_point_mm"
            )
        if (self.reference_tool_id is None) != (self.reference_pose is None):
            raise ValueError("reference_tool_id and reference_pose go together")
        return self


class XyzReferenceCalibration(PosesRequired):
    method: XyzReference
    poses: Annotated[
        list[Pose],
        PoseCount(
            1, 1, hint="one touch by the new tool; for several touches of one point use xyz_npoint"
        ),
    ]
    options: ReferenceOptions


def _reference(
    request: XyzReferenceCalibration, ctx: MethodContext, noise: float | None
) -> StoredPoint:
    options = request.options
    if options.reference_point_id is not None:
        return ctx.reference_point(options.reference_point_id)
    if options.reference_point_mm is not None:
        return StoredPoint(np.asarray(options.reference_point_mm, dtype=float), None)
    # the schema guarantees the third source: another tool's touch of the same point
    assert options.reference_tool_id is not None
    assert options.reference_pose is not None
    frame = ctx.tool_frame(options.reference_tool_id)
    with one_pose(("options", "reference_pose")):
        rotations, positions = ctx.parse_poses(
            request.format,
            [options.reference_pose],
            request.units,
            loc=("options", "reference_pose"),
        )
    point, covariance = reference_point_from_touch(
        tcp_mm=frame.position_mm,
        tcp_covariance_mm2=frame.covariance_mm2,
        rotation=rotations[0],
        position_mm=positions[0],
        touch_noise_mm=noise,
    )
    return StoredPoint(point, covariance)


def run(request: XyzReferenceCalibration, ctx: MethodContext) -> Solved:
    """t2 = R^T (r - f) with the uncertainty of r and of the touch propagated."""
    noise = touch_noise(request.options.touch_noise_mm, ctx)
    reference = _reference(request, ctx, noise)
    rotations, positions = ctx.parse_poses(
        request.format, request.poses, request.units, loc=("poses",)
    )
    result = solve_reference(
        reference_mm=reference.position_mm,
        reference_covariance_mm2=reference.covariance_mm2,
        rotation=rotations[0],
        position_mm=positions[0],
        touch_noise_mm=noise,
    )
    return Solved(
        position_mm=result.tcp_mm,
        quaternion=None,
        quality=QualityOut.from_solver(result.quality),
        warnings=list(result.quality.warnings),
        reference_point=StoredPoint(reference.position_mm, None),
    )


XYZ_REFERENCE = Method(
    request=XyzReferenceCalibration,
    run=run,
    description="one touch of a known point (a stored reference point, another tool's touch "
    "of it, or its coordinates) -> TCP position",
    example_body={
        "format": "kuka_abc",
        "poses": [[753.897, -81.965, 320.965, -108.243, -25.048, -167.066]],
        "options": {"reference_point_mm": [786.293, -194.53, 227.266]},
    },
)
