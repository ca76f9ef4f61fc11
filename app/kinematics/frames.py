"""Frames composed and inverted: a controller's reading of where the TCP is, turned into where
the flange is (flange = base * tcp * inverse(tool)).

A frame is (R, t): a rotation and a position in mm; composition is a @ b = (Ra Rb, Ra tb + ta)
and the inverse of (R, t) is (R^T, -R^T t). Rotations go through scipy's Rotation so that
quaternions [w, x, y, z] in and out are normalised and sign-consistent with app.kinematics.poses.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray

#: A frame as tcpcal stores one: position in mm and a unit quaternion [w, x, y, z].
Wxyz = tuple[float, float, float, float]
Xyz = tuple[float, float, float]

_IDENTITY: tuple[Xyz, Wxyz] = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))


def _rotation(quaternion: Sequence[float]) -> Rotation:
    w, x, y, z = (float(v) for v in quaternion)
    return Rotation.from_quat([x, y, z, w])


def _wxyz(rotation: Rotation) -> Wxyz:
    x, y, z, w = (float(v) for v in rotation.as_quat(canonical=True))
    return w, x, y, z


def compose(*frames: tuple[Sequence[float], Sequence[float]]) -> tuple[Xyz, Wxyz]:
    """The product a @ b @ ... of frames given as (position_mm [3], quaternion [w, x, y, z])."""
    position: FloatArray = np.zeros(3)
    rotation = Rotation.identity()
    for frame_position, frame_quaternion in frames:
        position = position + rotation.apply(np.asarray(frame_position, dtype=float))
        rotation = rotation * _rotation(frame_quaternion)
    x, y, z = (float(v) for v in position)
    return (x, y, z), _wxyz(rotation)


def inverse(position_mm: Sequence[float], quaternion: Sequence[float]) -> tuple[Xyz, Wxyz]:
    """The inverse of a frame: (R^T, -R^T t)."""
    rotation = _rotation(quaternion).inv()
    x, y, z = (float(v) for v in -rotation.apply(np.asarray(position_mm, dtype=float)))
    return (x, y, z), _wxyz(rotation)


def flange_from_tcp(
    tcp: tuple[Sequence[float], Sequence[float]],
    tool: tuple[Sequence[float], Sequence[float]] | None = None,
    base: tuple[Sequence[float], Sequence[float]] | None = None,
) -> tuple[Xyz, Wxyz]:
    """The flange in the robot's base frame from a controller's TCP reading: `tcp` is the
    tool frame `tool` (in the flange frame) as seen in the frame `base` (in the robot's base
    frame; a user frame, a base, as each maker's WireProtocol.frames addresses it):
    flange = base @ tcp @ inverse(tool).
    A missing tool or base is the identity (tool0, the world or robot base)."""
    tool_inverse = inverse(*tool) if tool is not None else _IDENTITY
    return compose(base if base is not None else _IDENTITY, tcp, tool_inverse)
