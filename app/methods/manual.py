"""`manual`: a TCP entered by hand, as numbers or as one pose (e.g. a pasted KRL $TOOL_DATA)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from app.methods.base import MethodContext, SolvedTcp, empty_quality
from app.schemas.calibrations import ManualCalibration
from app.solvers.validation import check_positions_mm, normalised_quaternions


def run(request: ManualCalibration, ctx: MethodContext) -> SolvedTcp:
    """The entered tool frame, checked like any pose."""
    if request.tcp is not None:
        position = check_positions_mm([request.tcp.position_mm], loc=("tcp", "position_mm"))[0]
        quaternion = None
        if request.tcp.quaternion is not None:
            quaternion = normalised_quaternions(
                [request.tcp.quaternion], loc=("tcp", "quaternion")
            )[0]
        return SolvedTcp(
            position_mm=position,
            quaternion=quaternion,
            algorithm=None,
            quality=empty_quality(0),
            graded=False,
        )

    if request.format is None or request.poses is None:  # the schema guarantees both
        raise ValueError("manual pose entry needs format and poses")
    rotations, positions = ctx.parse_poses(
        request.format, request.poses, request.units, loc=("poses",)
    )
    quaternion = np.asarray(
        Rotation.from_matrix(rotations[0]).as_quat(canonical=True, scalar_first=True)
    )
    return SolvedTcp(
        position_mm=positions[0],
        quaternion=quaternion,
        algorithm=None,
        quality=empty_quality(1),
        graded=False,
    )
