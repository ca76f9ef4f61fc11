"""Flange poses that bring a tool's TCP onto one point, from orientations in a reachable cone.

The cone is described relative to a start orientation R0 (base_from_flange): a touch is
R0 * Rot(a, tilt) * Rz(spin), where `a` is the unit vector at `azimuth` in the flange's
x-y plane. Tilt is then the angle between the touch's flange z axis (the tool axis) and the
start's; spin is the rotation about the tool axis. With the TCP t (flange frame, mm) on the
point p (base frame, mm), the flange sits at f = p - R t.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray


def cone_rotations(
    start: Rotation, tilt_deg: ArrayLike, azimuth_deg: ArrayLike, spin_deg: ArrayLike
) -> Rotation:
    """Orientations tilted by `tilt_deg` towards `azimuth_deg` and spun by `spin_deg` about the
    tool axis, relative to `start` (arrays of equal length)."""
    tilt = np.radians(np.atleast_1d(np.asarray(tilt_deg, dtype=float)))
    azimuth = np.radians(np.atleast_1d(np.asarray(azimuth_deg, dtype=float)))
    spin = np.atleast_1d(np.asarray(spin_deg, dtype=float))
    axes = np.stack([np.cos(azimuth), np.sin(azimuth), np.zeros_like(azimuth)], axis=1)
    tilts = Rotation.from_rotvec(axes * tilt[:, None])
    spins = Rotation.from_euler("z", spin[:, None], degrees=True)
    rotations: Rotation = start * tilts * spins
    return rotations


def flange_positions(rotations: Rotation, tcp_mm: ArrayLike, point_mm: ArrayLike) -> FloatArray:
    """Where the flange sits (N, 3) when each orientation puts the TCP on the point."""
    t = np.asarray(tcp_mm, dtype=float)
    p = np.asarray(point_mm, dtype=float)
    positions: FloatArray = p[None, :] - rotations.apply(t)
    return positions


def random_cone_rotations(
    rng: np.random.Generator, n: int, start: Rotation, *, max_tilt_deg: float, max_spin_deg: float
) -> Rotation:
    """n orientations uniform over the cone's spherical cap, spin uniform in +-max_spin_deg."""
    cos_max = np.cos(np.radians(max_tilt_deg))
    tilt = np.degrees(np.arccos(1.0 - rng.random(n) * (1.0 - cos_max)))
    azimuth = rng.random(n) * 360.0
    spin = (2.0 * rng.random(n) - 1.0) * max_spin_deg
    return cone_rotations(start, tilt, azimuth, spin)
