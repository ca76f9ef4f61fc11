"""Flange poses for a known tool frame Q (tool -> flange) and TCP t (mm, flange frame).

- `translation_directions`: pure translations along tool axes (ABB TCP&Z,X, Fanuc 6-point).
- `two_point_touches`: KUKA ABC 2-point touches of one fixed point.
- `world_aligned_rotation`: a flange rotation that puts tool axes on named base axes.
Noise: independent Gaussian on every recorded flange position coordinate, 1-sigma noise_mm.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from app.solvers.orientation import AxisDirection, Direction

_UNIT = {"x": 0, "y": 1, "z": 2}


def random_rotation(rng: np.random.Generator, max_deg: float) -> NDArray[np.float64]:
    """A random rotation of angle up to max_deg about a random axis."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    out: NDArray[np.float64] = Rotation.from_rotvec(
        axis * np.radians(rng.uniform(0.0, max_deg))
    ).as_matrix()
    return out


def tool_down(rng: np.random.Generator, max_deg: float = 30.0) -> NDArray[np.float64]:
    """A flange rotation with +Z roughly down, randomly varied by up to max_deg."""
    down = Rotation.from_euler("x", 180.0, degrees=True).as_matrix()
    out: NDArray[np.float64] = random_rotation(rng, max_deg) @ down
    return out


def _noisy(
    p: NDArray[np.float64], noise_mm: float, rng: np.random.Generator
) -> NDArray[np.float64]:
    if noise_mm <= 0.0:
        return p
    out: NDArray[np.float64] = p + rng.normal(0.0, noise_mm, size=3)
    return out


def translation_directions(
    Q: NDArray[np.float64],
    R: NDArray[np.float64],
    *,
    start_mm: Sequence[float] = (500.0, 100.0, 300.0),
    axes: Sequence[AxisDirection] = ("+z", "+x"),
    length_mm: float = 50.0,
    noise_mm: float = 0.0,
    rng: np.random.Generator | None = None,
) -> list[Direction]:
    """Pure flange translations of length_mm along the named tool axes, from start_mm.

    The tool axis in base is R Q e_axis; the TCP offset does not matter for a translation.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    f0 = np.asarray(start_mm, dtype=np.float64)
    out = []
    for i, axis in enumerate(axes):
        sign = 1.0 if axis[0] == "+" else -1.0
        v = R @ Q[:, _UNIT[axis[1]]]
        start = f0 + 5.0 * i  # each pair from its own start
        end = start + sign * length_mm * v
        out.append(
            Direction(
                axis=axis,
                rotation_from=R,
                position_from_mm=_noisy(start, noise_mm, rng),
                rotation_to=R,
                position_to_mm=_noisy(end, noise_mm, rng),
            )
        )
    return out


def two_point_touches(
    Q: NDArray[np.float64],
    t: NDArray[np.float64],
    *,
    point_mm: Sequence[float] = (600.0, -50.0, 120.0),
    working_axis: str = "x",
    lever_axis_mm: float = 60.0,
    lever_y_mm: float = 40.0,
    rotations: NDArray[np.float64] | None = None,
    noise_mm: float = 0.0,
    rng: np.random.Generator | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(rotations (3, 3, 3), positions (3, 3)): KUKA 2-point touches of `point_mm`.

    0: the TCP; 1: the point lever_axis_mm behind the TCP on the working axis; 2: a point
    lever_y_mm along tool +Y (and 10 mm back along the working axis) from the TCP.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    r = np.asarray(point_mm, dtype=np.float64)
    w = Q[:, _UNIT[working_axis]]
    y = Q[:, 1]
    points = [t, t - lever_axis_mm * w, t + lever_y_mm * y - 10.0 * w]
    if rotations is None:
        rotations = np.stack([tool_down(rng, 25.0) for _ in range(3)])
    positions = np.stack(
        [_noisy(r - Ri @ p, noise_mm, rng) for Ri, p in zip(rotations, points, strict=True)]
    )
    return rotations, positions


def world_aligned_rotation(
    Q: NDArray[np.float64], align: Mapping[str, str], *, spin_deg: float = 0.0
) -> NDArray[np.float64]:
    """Flange rotation R with R Q e_a = the named base direction for every aligned axis a.

    With a single axis (5D), `spin_deg` turns the pose about that base direction (free).
    """
    M = np.zeros((3, 3))
    named = {}
    for key, value in align.items():
        v = np.zeros(3)
        v[_UNIT[value[-1]]] = -1.0 if value.startswith("-") else 1.0
        M[:, _UNIT[key]] = v
        named[_UNIT[key]] = v
    if len(named) == 1:
        ((a, v),) = named.items()
        # Complete with any right-handed frame around v.
        helper = np.array([1.0, 0.0, 0.0]) if abs(v[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        b = np.cross(v, helper)
        b /= np.linalg.norm(b)
        M[:, (a + 1) % 3] = b
        M[:, (a + 2) % 3] = np.cross(v, b)
        spin = Rotation.from_rotvec(np.radians(spin_deg) * v).as_matrix()
        M = spin @ M
    elif len(named) == 2:
        missing = ({0, 1, 2} - set(named)).pop()
        M[:, missing] = np.cross(M[:, (missing + 1) % 3], M[:, (missing + 2) % 3])
    out: NDArray[np.float64] = M @ Q.T
    return out
