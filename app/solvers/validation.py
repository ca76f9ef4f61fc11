"""Input checks shared by every library that takes poses: one definition of "a valid pose"."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput

#: Largest coordinate accepted, mm (100 m). A tracker that lost the tool reports about
#: -3.7e28; such sentinels must be refused, never averaged.
MAX_ABS_MM = 100_000.0
#: Orthonormality tolerance of a rotation matrix: max |R R^T - I|.
ROTATION_ATOL = 1e-6
#: Tolerance on the norm of a quaternion before it is normalised.
QUATERNION_NORM_ATOL = 1e-3

Loc = Sequence[str | int]


def check_finite(values: ArrayLike, *, loc: Loc = ()) -> FloatArray:
    """Return `values` as a float array; InvalidInput("non-finite") naming the first bad index."""
    arr = np.asarray(values, dtype=np.float64)
    bad = ~np.isfinite(arr)
    if bad.any():
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        raise InvalidInput(
            "non-finite",
            f"value {arr[index]} at index {list(index)} is not a finite number",
            loc=(*loc, *index),
        )
    return arr


def check_positions_mm(positions: ArrayLike, *, loc: Loc = ("poses",)) -> FloatArray:
    """Check an (N, 3) array of positions in mm: finite and within 100 m of the origin."""
    arr = check_finite(positions, loc=loc)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InvalidInput(
            "invalid-pose", f"positions must have shape (N, 3), got {arr.shape}", loc=loc
        )
    too_far = np.abs(arr) > MAX_ABS_MM
    if too_far.any():
        i, j = (int(k) for k in np.argwhere(too_far)[0])
        raise InvalidInput(
            "out-of-range",
            f"pose {i + 1}: coordinate {'xyz'[j]} = {arr[i, j]:.6g} mm is beyond 100 m "
            "(a tracker or controller that lost the tool reports values like -3.7e28)",
            loc=(*loc, i, "position"),
        )
    return arr


def check_rotation_matrices(
    rotations: ArrayLike, *, loc: Loc = ("poses",), atol: float = ROTATION_ATOL
) -> FloatArray:
    """Check an (N, 3, 3) array of rotation matrices: finite, orthonormal and det +1."""
    arr = check_finite(rotations, loc=loc)
    if arr.ndim != 3 or arr.shape[1:] != (3, 3):
        raise InvalidInput(
            "invalid-pose", f"rotations must have shape (N, 3, 3), got {arr.shape}", loc=loc
        )
    eye = np.eye(3)
    err = np.abs(arr @ np.swapaxes(arr, 1, 2) - eye).max(axis=(1, 2))
    det = np.linalg.det(arr)
    for i in map(int, np.flatnonzero((err > atol) | (det < 0))):  # usually none
        if err[i] > atol:
            raise InvalidInput(
                "invalid-rotation",
                f"pose {i + 1}: rotation is not orthonormal: max|R R^T - I| = {err[i]:.1e} "
                f"(tolerance {atol:.0e})",
                loc=(*loc, i, "rotation"),
            )
        if det[i] < 0:
            raise InvalidInput(
                "invalid-rotation",
                f"pose {i + 1}: rotation has det {det[i]:.6f}; a rotation needs det +1 "
                "(this is a reflection)",
                loc=(*loc, i, "rotation"),
            )
    return arr


def normalised_quaternions(
    quaternions: ArrayLike, *, loc: Loc = ("poses",), atol: float = QUATERNION_NORM_ATOL
) -> FloatArray:
    """Check (N, 4) quaternions (any component order) have norm within `atol` of 1; normalise."""
    arr = check_finite(quaternions, loc=loc)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise InvalidInput(
            "invalid-pose", f"quaternions must have shape (N, 4), got {arr.shape}", loc=loc
        )
    norms = np.linalg.norm(arr, axis=1)
    for i, n in enumerate(norms):
        if abs(n - 1.0) > atol:
            raise InvalidInput(
                "invalid-rotation",
                f"pose {i + 1}: quaternion norm is {n:.6f}; it must be within {atol:g} of 1",
                loc=(*loc, i, "quaternion"),
            )
    normalised: FloatArray = arr / norms[:, None]
    return normalised
