"""Seeded simulator of XYZ N-point touches: flange poses that bring a known TCP to a known point.

The nominal pose holds the tool pointing down (flange z along base -z). Each touch tilts the
tool axis to a direction drawn uniformly from a cone of half-angle `tilt_deg` around that
nominal axis, optionally spun about the tool axis by a uniform angle. The flange position then
follows from the true TCP and point; touch noise, orientation noise and gross outliers (a
touch that missed the point by `outlier_mm`) are added to what the controller would report.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray

#: Flange orientation with the tool pointing straight down.
TOOL_DOWN = Rotation.from_euler("x", 180.0, degrees=True)


@dataclass(frozen=True)
class Touches:
    """Simulated touches: measured R (N, 3, 3), f (N, 3) mm; truth t (3,), p (3,); outlier mask."""

    R: FloatArray
    f: FloatArray
    t: FloatArray
    p: FloatArray
    outliers: NDArray[np.bool_]
    R_true: FloatArray


def random_tcp(rng: np.random.Generator, norm_mm: float, max_tilt_deg: float = 30.0) -> FloatArray:
    """A TCP of length `norm_mm` (mm) within `max_tilt_deg` of the flange z axis."""
    axis = _cone_directions(rng, 1, max_tilt_deg)[0]
    tcp: FloatArray = norm_mm * axis
    return tcp


def _cone_directions(rng: np.random.Generator, n: int, half_angle_deg: float) -> FloatArray:
    """n unit vectors uniform on the spherical cap of half-angle around +z."""
    cos_max = np.cos(np.radians(half_angle_deg))
    cos_theta = 1.0 - rng.random(n) * (1.0 - cos_max)
    sin_theta = np.sqrt(np.clip(1.0 - cos_theta**2, 0.0, None))
    phi = rng.random(n) * 2.0 * np.pi
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=1)


def touch_rotations(rng: np.random.Generator, n: int, *, tilt_deg: float, spin: bool) -> Rotation:
    """n flange orientations: tool axis in a cone around tool-down, optional spin about it."""
    down = np.array([0.0, 0.0, -1.0])
    dirs = -_cone_directions(rng, n, tilt_deg)  # tool axis directions in the base frame
    axes = np.cross(down, dirs)
    s = np.linalg.norm(axes, axis=1)
    angle = np.arctan2(s, dirs @ down)
    safe = np.where(s > 0, s, 1.0)[:, None]
    tilt = Rotation.from_rotvec(axes / safe * angle[:, None])
    spin_deg = rng.uniform(-180.0, 180.0, n) if spin else np.zeros(n)
    return tilt * TOOL_DOWN * Rotation.from_euler("z", spin_deg[:, None], degrees=True)


def simulate_touches(
    n: int,
    *,
    seed: int,
    tilt_deg: float = 30.0,
    spin: bool = True,
    tcp_norm_mm: float = 150.0,
    touch_noise_mm: float = 0.05,
    orientation_noise_deg: float = 0.0,
    outlier_fraction: float = 0.0,
    outlier_mm: float = 5.0,
    tcp_mm: FloatArray | None = None,
    pivot_mm: FloatArray | None = None,
) -> Touches:
    """N touches of one point, seeded; noise 1-sigma per axis; outliers of exactly `outlier_mm`."""
    rng = np.random.default_rng(seed)
    t = random_tcp(rng, tcp_norm_mm) if tcp_mm is None else np.asarray(tcp_mm, dtype=float)
    p = (
        np.array([800.0, -150.0, 250.0]) + rng.normal(0.0, 50.0, 3)
        if pivot_mm is None
        else np.asarray(pivot_mm, dtype=float)
    )
    rot_true = touch_rotations(rng, n, tilt_deg=tilt_deg, spin=spin)
    R_true = rot_true.as_matrix()
    f = p - np.einsum("nij,j->ni", R_true, t) + rng.normal(0.0, touch_noise_mm, (n, 3))
    if orientation_noise_deg > 0:
        delta = Rotation.from_rotvec(np.radians(rng.normal(0.0, orientation_noise_deg, (n, 3))))
        R = (rot_true * delta).as_matrix()
    else:
        R = R_true.copy()
    mask = np.zeros(n, dtype=bool)
    k = round(outlier_fraction * n)
    if k:
        idx = rng.choice(n, size=k, replace=False)
        mask[idx] = True
        d = rng.normal(size=(k, 3))
        f[idx] += outlier_mm * d / np.linalg.norm(d, axis=1, keepdims=True)
    return Touches(R=R, f=f, t=t, p=p, outliers=mask, R_true=R_true)


def coaxial_rotations(n: int, *, axis_flange: FloatArray, seed: int = 0) -> FloatArray:
    """n tool-down orientations that differ only by rotation about one flange axis (degenerate)."""
    rng = np.random.default_rng(seed)
    axis = np.asarray(axis_flange, dtype=float) / np.linalg.norm(axis_flange)
    angles = np.radians(np.linspace(-60.0, 60.0, n) + rng.uniform(-5, 5, n))
    matrices: FloatArray = (TOOL_DOWN * Rotation.from_rotvec(angles[:, None] * axis)).as_matrix()
    return matrices
