"""`manual` for a frame: a frame entered by hand, as numbers or as one pose (a pasted
BASE_DATA, UFRAME or wobjdata), in the robot's base frame. Nothing is touched, so there is
no pointer, no residual and no uncertainty."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import ConfigDict, Field, field_validator, model_validator
from scipy.spatial.transform import Rotation

from app.methods.base import PoseCount
from app.methods.frame.base import FrameContext, FrameMethod, FrameMethodRequest, FrameSolved
from app.methods.manual import NoOptions
from app.schemas.common import Pose, Quaternion, StrictModel, Vec3, one_of
from app.schemas.frame_results import FrameQuality
from app.solvers.validation import check_positions_mm, normalised_quaternions
from app.words import Manual

#: The base frame's axes, [w, x, y, z]: a frame entered without an orientation.
BASE_AXES = (1.0, 0.0, 0.0, 0.0)


class ManualFrameIn(StrictModel):
    position_mm: Vec3
    quaternion: Quaternion | None = Field(
        default=None, description="[w, x, y, z], frame -> base; absent: the base frame's axes"
    )


class ManualFrameCalibration(FrameMethodRequest):
    model_config = ConfigDict(
        json_schema_extra=one_of(
            (("frame",), ("format", "poses")), (("format", "poses"), ("frame",))
        )
    )

    method: Manual
    poses: (
        Annotated[list[Pose], PoseCount(1, 1, hint="the frame, in the robot's base frame")] | None
    ) = None
    frame: ManualFrameIn | None = Field(
        default=None, description="the frame as numbers (or give format + poses instead)"
    )
    options: NoOptions = Field(default_factory=NoOptions)
    #: Nothing is touched: the schema says so (null only), and a pointer sent is refused at
    #: its field in words (a schema allowing a string here that the model then refused is a
    #: schema that lies: the contract test's schema_valid_is_not_refused_by_the_schema).
    tool_id: None = Field(default=None, description="none: a frame entered by hand has no pointer")
    tcp_version: None = Field(default=None, description="none: no pointer, so no TCP version")

    @field_validator("tool_id", "tcp_version", mode="before")
    @classmethod
    def _no_pointer(cls, value: object) -> None:
        if value is not None:
            raise ValueError(
                "a frame entered by hand is touched with no pointer: leave out tool_id and "
                "tcp_version"
            )
        return None

    @model_validator(mode="after")
    def _frame_or_pose(self) -> ManualFrameCalibration:
        has_pose = self.poses is not None or self.format is not None
        if (self.frame is None) == (not has_pose):
            raise ValueError("give either frame, or format + poses with exactly one pose")
        if has_pose and (self.format is None or self.poses is None):
            raise ValueError("manual with format + poses takes exactly one pose: the frame")
        return self


def run(request: ManualFrameCalibration, ctx: FrameContext) -> FrameSolved:
    """The entered frame, checked like any pose."""
    if request.frame is not None:
        position = check_positions_mm([request.frame.position_mm], loc=("frame", "position_mm"))[0]
        given = request.frame.quaternion
        quaternion = (
            np.array(BASE_AXES)
            if given is None
            else normalised_quaternions([given], loc=("frame", "quaternion"))[0]
        )
    else:
        # the schema guarantees format + one pose when frame is absent
        assert request.format is not None
        assert request.poses is not None
        rotations, positions = ctx.parse_poses(
            request.format, request.poses, request.units, loc=("poses",)
        )
        position = positions[0]
        quaternion = np.asarray(
            Rotation.from_matrix(rotations[0]).as_quat(canonical=True, scalar_first=True)
        )
    return FrameSolved(
        position_mm=np.asarray(position, dtype=float),
        quaternion=np.asarray(quaternion, dtype=float),
        quality=FrameQuality(
            n_touches=0,
            rms_mm=None,
            max_mm=None,
            residuals_mm=[],
            position_sigma_mm=None,
            angle_sigma_deg=None,
            sigma_source=None,
            interval95_scale=None,
            outliers=[],
        ),
        points_mm=np.zeros((0, 3)),
        tool=None,
        summary="entered by hand: nothing was touched, so no uncertainty is known",
        fiducials=[],
        graded=False,
    )


MANUAL_FRAME = FrameMethod(
    request=ManualFrameCalibration,
    run=run,
    description="a frame entered by hand, as numbers or as one pose (e.g. a pasted BASE_DATA)",
    example_body={
        "frame": {"position_mm": [1200.0, -350.0, 420.0], "quaternion": [1.0, 0.0, 0.0, 0.0]},
        "note": "from the fixture drawing",
    },
    measured=False,
)
