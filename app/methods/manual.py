"""`manual`: a TCP entered by hand, as numbers or as one pose (e.g. a pasted KRL $TOOL_DATA)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import ConfigDict, Field, model_validator
from scipy.spatial.transform import Rotation

from app.methods.base import Method, MethodContext, MethodRequest, PoseCount, Solved
from app.schemas.common import Pose, Quaternion, StrictModel, Vec3, one_of
from app.schemas.results import QualityOut
from app.solvers.validation import check_positions_mm, normalised_quaternions
from app.words import Manual


class ManualTcpIn(StrictModel):
    position_mm: Vec3
    quaternion: Quaternion | None = None


class NoOptions(StrictModel):
    """This method takes no options."""


class ManualCalibration(MethodRequest):
    model_config = ConfigDict(
        json_schema_extra=one_of((("tcp",), ("format", "poses")), (("format", "poses"), ("tcp",)))
    )

    method: Manual
    poses: (
        Annotated[list[Pose], PoseCount(1, 1, hint="the tool frame relative to the flange")] | None
    ) = None
    tcp: ManualTcpIn | None = None
    options: NoOptions = Field(default_factory=NoOptions)

    @model_validator(mode="after")
    def _tcp_or_pose(self) -> ManualCalibration:
        has_pose = self.poses is not None or self.format is not None
        if (self.tcp is None) == (not has_pose):
            raise ValueError("give either tcp, or format + poses with exactly one pose")
        if has_pose and (self.format is None or self.poses is None):
            raise ValueError("manual with format + poses takes exactly one pose: the tool frame")
        return self


def run(request: ManualCalibration, ctx: MethodContext) -> Solved:
    """The entered tool frame, checked like any pose."""
    if request.tcp is not None:
        position = check_positions_mm([request.tcp.position_mm], loc=("tcp", "position_mm"))[0]
        quaternion = None
        if request.tcp.quaternion is not None:
            quaternion = normalised_quaternions(
                [request.tcp.quaternion], loc=("tcp", "quaternion")
            )[0]
        return Solved(
            position_mm=position,
            quaternion=quaternion,
            quality=QualityOut.ungraded(0),
            graded=False,
        )
    # the schema guarantees format + one pose when tcp is absent
    assert request.format is not None
    assert request.poses is not None
    rotations, positions = ctx.parse_poses(
        request.format, request.poses, request.units, loc=("poses",)
    )
    quaternion = np.asarray(
        Rotation.from_matrix(rotations[0]).as_quat(canonical=True, scalar_first=True)
    )
    return Solved(
        position_mm=positions[0],
        quaternion=quaternion,
        quality=QualityOut.ungraded(1),
        graded=False,
    )


MANUAL = Method(
    request=ManualCalibration,
    run=run,
    description="a TCP entered by hand, as numbers or as one pose (e.g. a pasted $TOOL_DATA)",
    example_body={"tcp": {"position_mm": [0.0, 0.0, 150.0]}, "note": "data sheet"},
    measured=False,
)
