"""Seeded simulator of frame touches: a pointer tool touching known points of a cell frame.

A true frame (R, o) stands in the robot's base frame; its points n_k (frame coordinates) are
touched by a pointer whose true TCP is t. Each touch holds the tool roughly down (tilted up
to `tilt_deg` about a random axis), so the flange is f = R n + o - R_flange t. What the
solver is handed: the flange poses, the pointer's TCP as calibrated (t + dt, dt drawn once
per set from the TCP's covariance: the error every touch shares) and each flange position
with the touch error (1-sigma `touch_noise_mm` per axis).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from testbed.sim.touches import TOOL_DOWN


@dataclass(frozen=True)
class FrameTouches:
    """Touches of known frame points: flange rotations (N, 3, 3), positions (N, 3) mm as
    measured, the pointer's TCP as calibrated (3,), and the truth."""

    rotations: FloatArray
    positions_mm: FloatArray
    tcp_mm: FloatArray
    nominal_mm: FloatArray
    frame_rotation: FloatArray
    frame_origin_mm: FloatArray
    tcp_true_mm: FloatArray


def random_frame(
    rng: np.random.Generator, reach_mm: float = 800.0
) -> tuple[FloatArray, FloatArray]:
    """A frame anywhere in a robot's reach: any rotation, origin within `reach_mm`."""
    R: FloatArray = Rotation.random(random_state=rng).as_matrix()
    o: FloatArray = rng.uniform(-reach_mm, reach_mm, size=3)
    return R, o


def flange_rotations(rng: np.random.Generator, n: int, tilt_deg: float) -> FloatArray:
    """n flange rotations with the tool roughly down, each tilted up to `tilt_deg`."""
    turns = Rotation.from_rotvec(
        (v := rng.normal(size=(n, 3)))
        / np.linalg.norm(v, axis=1, keepdims=True)
        * np.radians(rng.uniform(0.0, tilt_deg, size=(n, 1)))
    )
    out: FloatArray = (turns * TOOL_DOWN).as_matrix()
    return out


def touch_frame(
    rng: np.random.Generator,
    nominal_mm: FloatArray,
    *,
    frame: tuple[FloatArray, FloatArray] | None = None,
    tcp_mm: FloatArray | None = None,
    touch_noise_mm: float = 0.0,
    tcp_sigma_mm: float = 0.0,
    tilt_deg: float = 20.0,
    gross: dict[int, float] | None = None,
) -> FrameTouches:
    """Touches of the nominal points (N, 3) mm of a frame (random unless given); `gross`
    moves touch i by that many mm in a random direction (a missed point)."""
    R, o = frame if frame is not None else random_frame(rng)
    t = np.array([1.5, -2.0, 180.0]) if tcp_mm is None else np.asarray(tcp_mm, dtype=float)
    n = nominal_mm.shape[0]
    rotations = flange_rotations(rng, n, tilt_deg)
    targets = nominal_mm @ R.T + o
    positions = targets - np.einsum("nij,j->ni", rotations, t)
    positions = positions + rng.normal(0.0, touch_noise_mm, size=(n, 3)) * (touch_noise_mm > 0)
    for i, mm in (gross or {}).items():
        d = rng.normal(size=3)
        positions[i] += mm * d / np.linalg.norm(d)
    calibrated = t + rng.normal(0.0, tcp_sigma_mm, size=3) * (tcp_sigma_mm > 0)
    return FrameTouches(rotations, positions, calibrated, nominal_mm, R, o, t)


#: A fixture's points (frame coordinates, mm): a 500 x 300 mm plate, two pins raised.
FIXTURE_MM: FloatArray = np.array(
    [
        [0.0, 0.0, 0.0],
        [500.0, 0.0, 0.0],
        [500.0, 300.0, 0.0],
        [0.0, 300.0, 0.0],
        [250.0, 150.0, 40.0],
        [100.0, 250.0, 25.0],
    ]
)
