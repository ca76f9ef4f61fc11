"""fixed_npoint: a stationary tool's tip, touched by a pointer whose TCP is not trusted.

The N-point model R_i t + f_i = c, with both t (the pointer's TCP, flange frame) and c (the
fixed tip, base frame) unknown, is the pivot fit `app.solvers.npoint` solves: c is the
stationary TCP (METHODS.md 7), found with the same estimators, outlier handling and
covariance. Its orientation: `options.align` read as an ABC World alignment
(orientation_from_world) with the base frame as the reference (tool axes named onto base
directions), three more role touches of the tool's own frame (origin, x, xy: `construction`,
touched with the TCP just found), or else the base frame's axes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.solvers.npoint import NPointResult, solve_npoint
from app.solvers.orientation import orientation_from_world
from app.words import Algorithm


@dataclass(frozen=True)
class FixedTip:
    """The tip (3,) mm in the base frame with its covariance, the pointer's TCP found, and
    the tool frame's rotation (3, 3) tool -> base."""

    tip_mm: FloatArray
    tip_covariance_mm2: FloatArray
    pointer: NPointResult
    rotation: FloatArray
    warnings: tuple[str, ...]


def fixed_tip(
    rotations: ArrayLike,
    positions_mm: ArrayLike,
    *,
    align: Mapping[str, str] | None = None,
    algorithm: Algorithm = "robust",
    touch_noise_mm: float | None = None,
) -> FixedTip:
    """The stationary tip from N >= 4 pivot touches: flange rotations (N, 3, 3), flange
    positions (N, 3) mm; `align` maps tool axes to base directions ({"z": "-z"})."""
    solved = solve_npoint(
        rotations, positions_mm, algorithm=algorithm, touch_noise_mm=touch_noise_mm
    )
    warnings = list(solved.quality.warnings)
    rotation = np.eye(3)
    if align is not None:
        aligned = orientation_from_world(rotation=np.eye(3), align=align, working_axis="z")
        rotation = aligned.rotation
        warnings += [w for w in aligned.warnings if "working axis" not in w]
    return FixedTip(
        tip_mm=solved.pivot_mm,
        tip_covariance_mm2=solved.pivot_covariance_mm2,
        pointer=solved,
        rotation=rotation,
        warnings=tuple(warnings),
    )
