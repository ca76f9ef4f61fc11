"""Seeded simulator of plane touches: flange poses that put a known TCP on known flat surfaces.

Each plane has a unit normal within `plane_tilt_deg` of base +z (a table, tilted a little) or,
for a second and third plane, of base +x / +y (walls); its offset puts it near the work
area. Each touch: a tool orientation from the N-point simulator's cone (tool pointing into the
plane, tilted up to `tilt_deg`, optionally spun), a touch point drawn uniformly within
`spread_mm` of the plane's centre, and the flange position that brings the TCP there. Touch
noise (1-sigma per axis, mm) is added to the flange position as a controller would report it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from testbed.sim.touches import random_tcp, touch_rotations

#: Centres of the planes a, b, c (mm, base frame) and the base axis each faces.
CENTRES = (
    np.array([800.0, -150.0, 250.0]),
    np.array([1100.0, -150.0, 450.0]),
    np.array([800.0, 200.0, 450.0]),
)
FACING = (np.array([0.0, 0.0, 1.0]), np.array([-1.0, 0.0, 0.0]), np.array([0.0, -1.0, 0.0]))


@dataclass(frozen=True)
class PlaneTouches:
    """Measured R (N, 3, 3), f (N, 3) mm; truth t (3,), normals (K, 3), offsets (K,); labels."""

    R: FloatArray
    f: FloatArray
    t: FloatArray
    normals: FloatArray
    offsets: FloatArray
    labels: list[str]


def _into(direction: FloatArray) -> Rotation:
    """The rotation taking base -z (the simulator's tool-down axis) onto -direction."""
    down = np.array([0.0, 0.0, -1.0])
    target = -direction / np.linalg.norm(direction)
    axis = np.cross(down, target)
    s = float(np.linalg.norm(axis))
    if s < 1e-12:
        return (
            Rotation.identity()
            if target @ down > 0
            else Rotation.from_euler("x", 180, degrees=True)
        )
    return Rotation.from_rotvec(axis / s * np.arctan2(s, float(target @ down)))


def simulate_plane_touches(
    n: int,
    *,
    seed: int,
    planes: int = 1,
    tilt_deg: float = 30.0,
    spin: bool = True,
    tcp_norm_mm: float = 150.0,
    touch_noise_mm: float = 0.05,
    spread_mm: float = 80.0,
    plane_tilt_deg: float = 10.0,
    tcp_mm: FloatArray | None = None,
) -> PlaneTouches:
    """N touches spread over `planes` planes (round robin a, b, c), seeded."""
    rng = np.random.default_rng(seed)
    t = random_tcp(rng, tcp_norm_mm) if tcp_mm is None else np.asarray(tcp_mm, dtype=float)
    normals, offsets, frames = [], [], []
    for k in range(planes):
        wobble = Rotation.from_rotvec(
            np.radians(plane_tilt_deg) * rng.uniform(-1.0, 1.0) * _unit(rng.normal(size=3))
        )
        normal = wobble.apply(FACING[k])
        normals.append(normal)
        offsets.append(float(normal @ CENTRES[k]))
        frames.append(_into(normal))
    labels = [("a", "b", "c")[i % planes] for i in range(n)]
    index = np.array([i % planes for i in range(n)])
    rel = touch_rotations(rng, n, tilt_deg=tilt_deg, spin=spin)
    R = np.empty((n, 3, 3))
    f = np.empty((n, 3))
    for i in range(n):
        k = int(index[i])
        # the simulator's cone is around tool-down (base -z); turn it to face plane k
        rot = frames[k] * rel[i]
        R[i] = rot.as_matrix()
        e1 = _unit(np.cross(normals[k], [0.3, 0.5, 0.7]))
        e2 = np.cross(normals[k], e1)
        u, v = rng.uniform(-spread_mm, spread_mm, 2)
        point = CENTRES[k] + u * e1 + v * e2  # the centre lies on the plane
        f[i] = point - R[i] @ t
    f += rng.normal(0.0, touch_noise_mm, f.shape)
    return PlaneTouches(
        R=R, f=f, t=t, normals=np.array(normals), offsets=np.array(offsets), labels=labels
    )


def _unit(v: NDArray[np.float64] | list[float]) -> FloatArray:
    a = np.asarray(v, dtype=float)
    out: FloatArray = a / np.linalg.norm(a)
    return out
