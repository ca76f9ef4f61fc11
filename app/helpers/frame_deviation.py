"""How far apart two tool frames are: the distance of their points and the angle between
their rotations (what a deployment's read-back and a reconcile compare)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from app.kinematics.poses import rotation_angle_deg

#: A deployment is verified when the controller reads back within these of what was written.
DEPLOY_TOLERANCE_MM = 0.001
DEPLOY_TOLERANCE_DEG = 0.001
#: A reconcile finds a tool in sync when the controller holds the active TCP within these.
SYNC_TOLERANCE_MM = 0.01
SYNC_TOLERANCE_DEG = 0.01


def frame_deviation(
    position_a_mm: Sequence[float],
    quaternion_a: Sequence[float],
    position_b_mm: Sequence[float],
    quaternion_b: Sequence[float],
) -> tuple[float, float]:
    """(distance in mm, rotation angle in deg) between frame a and frame b; quaternions
    [w, x, y, z] (q and -q are the same rotation: the angle is the same)."""
    distance = float(np.linalg.norm(np.asarray(position_a_mm) - np.asarray(position_b_mm)))
    return distance, float(rotation_angle_deg(quaternion_a, quaternion_b))


def within(deviation: tuple[float, float], *, mm: float, deg: float) -> bool:
    """True when both parts of a frame_deviation are within the limits."""
    return deviation[0] <= mm and deviation[1] <= deg


def frames_within(
    position_a_mm: Sequence[float],
    quaternion_a: Sequence[float],
    position_b_mm: Sequence[float],
    quaternion_b: Sequence[float],
    *,
    mm: float,
    deg: float,
) -> bool:
    """True when frame a is within `mm` and `deg` of frame b, as within(frame_deviation(...))
    says: a frame equal to the other in every number is, one whose point is further than `mm`
    is not, and only otherwise is the rotation between them computed (the part of a
    frame_deviation that costs: a reconcile round compares the frame a robot moves by with
    the flange, its last read and each version of its tools)."""
    if tuple(position_a_mm) == tuple(position_b_mm) and tuple(quaternion_a) == tuple(quaternion_b):
        return True
    if math.dist(position_a_mm, position_b_mm) > mm:
        return False
    return float(rotation_angle_deg(quaternion_a, quaternion_b)) <= deg
