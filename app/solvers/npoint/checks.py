"""Input checks of the N-point method: touches, options, repeated orientations, the conditioning of
the touch geometry, and the predicted sigma against the tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import get_args

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.noise_limits import MAX_TOUCH_NOISE_MM, MIN_TOUCH_NOISE_MM
from app.solvers.npoint.model import Noise
from app.solvers.numbering import number
from app.solvers.quality import (
    format_vector,
)
from app.solvers.validation import MAX_ABS_MM, check_positions_mm, check_rotation_matrices
from app.words import Algorithm

#: The N-point estimators (`options.algorithm`: app.words.Algorithm); the tuple is read off
#: the Literal.
ALGORITHMS: tuple[Algorithm, ...] = get_args(Algorithm)
#: Fewest touches the method accepts (the "XYZ 4-point" method of the pendants).
MIN_POSES = 4
#: Two touches whose orientations differ by less than this (deg) count as one orientation.
REPEATED_POSE_DEG = 0.5
#: Refuse when s_min / s_max of the centred TCP block [R_i - mean(R)] is below this: the TCP
#: component along the weakest direction is then at least 100x worse determined than the best.
DEGENERACY_RATIO = 1e-2
#: Warn (but solve) when that ratio is below this.
WEAK_DIRECTION_RATIO = 0.1
#: Upper bound on the orientation noise option, to catch unit mistakes (rad for deg); the
#: touch noise's bounds are in app.solvers.noise_limits.
MAX_ORIENTATION_NOISE_DEG = 10.0


def checked_touches(rotations: ArrayLike, positions_mm: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """The touches as (N, 3, 3) rotations and (N, 3) positions, at least MIN_POSES of them."""
    R = check_rotation_matrices(rotations, loc=("poses",))
    f = check_positions_mm(positions_mm, loc=("poses",))
    if R.shape[0] != f.shape[0]:
        raise InvalidInput(
            "invalid-pose",
            f"got {R.shape[0]} rotations but {f.shape[0]} positions; each touch needs both",
            loc=("poses",),
        )
    n = R.shape[0]
    if n < MIN_POSES:
        raise InvalidInput(
            "too-few-poses",
            f"{n} touch(es) given; the N-point method needs at least {MIN_POSES} touches of "
            "the same point from clearly different orientations",
            loc=("poses",),
            context={"n_poses": n, "min_poses": MIN_POSES},
        )
    return R, f


def geometry_warnings(block: Block, algorithm: Algorithm) -> list[str]:
    """Say when the touch geometry or the chosen estimator limits the result."""
    warnings = []
    if block.ratio < WEAK_DIRECTION_RATIO:
        warnings.append(
            f"the TCP along the flange direction {format_vector(block.weakest)} is weakly "
            f"determined (singular value ratio {block.ratio:.3f}): add a touch rotated about "
            "a different axis"
        )
    if algorithm == "sphere":
        warnings.append(
            "the sphere fit is a textbook baseline, biased under touch noise: use the default "
            "algorithm (robust) for a TCP to keep"
        )
    return warnings


def check_predicted_sigma(
    cov_t: FloatArray, max_tcp_sigma_mm: float, s_p: float, noise: Noise
) -> None:
    """Refuse when the TCP's 1-sigma along its weakest direction exceeds the tolerance."""
    evals, evecs = np.linalg.eigh(0.5 * (cov_t + cov_t.T))
    worst = float(np.sqrt(max(float(evals[-1]), 0.0)))
    if worst <= max_tcp_sigma_mm:
        return
    direction = _canonical_direction(evecs[:, -1])
    source = (
        f"the configured touch noise of {s_p:g} mm"
        if noise.touch_mm is not None
        else f"the touch noise estimated from the residuals ({s_p:.3g} mm)"
    )
    raise InvalidInput(
        "insufficient-spread",
        f"with {source} the TCP is only determined to {worst:.3g} mm (1 sigma) along "
        f"the flange direction {format_vector(direction)}, more than the allowed "
        f"{max_tcp_sigma_mm:g} mm: touch from orientations further apart (tilt the "
        "tool more, about different axes)",
        loc=("poses",),
        context={
            "predicted_sigma_mm": worst,
            "max_tcp_sigma_mm": float(max_tcp_sigma_mm),
            "direction_flange": [float(x) for x in direction],
        },
    )


def check_options(
    algorithm: str,
    touch_noise_mm: float | None,
    orientation_noise_deg: float | None,
    max_tcp_sigma_mm: float | None,
) -> Noise:
    if algorithm not in ALGORITHMS:
        raise InvalidInput(
            "invalid-options",
            f"unknown algorithm {algorithm!r}; choose one of {', '.join(ALGORITHMS)}",
            loc=("options", "algorithm"),
        )
    checks = (
        ("touch_noise_mm", touch_noise_mm, MAX_TOUCH_NOISE_MM, "mm", MIN_TOUCH_NOISE_MM),
        ("orientation_noise_deg", orientation_noise_deg, MAX_ORIENTATION_NOISE_DEG, "deg", 0.0),
        ("max_tcp_sigma_mm", max_tcp_sigma_mm, MAX_ABS_MM, "mm", MIN_TOUCH_NOISE_MM),
    )
    for name, value, upper, unit, lower in checks:
        if value is None:
            continue
        v = float(value)
        if not (math.isfinite(v) and lower <= v <= upper):
            raise InvalidInput(
                "invalid-options",
                f"{name} = {value!r} is not usable: it must be a number from {lower:g} to "
                f"{upper:g} {unit}",
                loc=("options", name),
            )
    return Noise(
        touch_mm=None if touch_noise_mm is None else float(touch_noise_mm),
        orientation_rad=math.radians(float(orientation_noise_deg or 0.0)),
    )


def relative_cosines(R: FloatArray) -> FloatArray:
    """(N, N) cosine of the rotation angle between every pair: (trace(R_i^T R_j) - 1) / 2."""
    flat = R.reshape(R.shape[0], 9)
    out: FloatArray = 0.5 * (flat @ flat.T - 1.0)
    return out


def check_repeated(cosines: FloatArray) -> list[str]:
    """Name touches that repeat an orientation; refuse if fewer than 4 distinct remain."""
    n = cosines.shape[0]
    close = cosines > math.cos(math.radians(REPEATED_POSE_DEG))
    np.fill_diagonal(close, False)
    if not close.any():
        return []
    close = np.triu(close, k=1)
    pairs = [(int(i), int(j)) for i, j in np.argwhere(close)]
    distinct = n - int(close.any(axis=0).sum())
    shown = ", ".join(f"{number(i)} and {number(j)}" for i, j in pairs[:10])
    more = f" (and {len(pairs) - 10} more pairs)" if len(pairs) > 10 else ""
    if distinct < MIN_POSES:
        raise InvalidInput(
            "repeated-poses",
            f"touches {shown}{more} have the same orientation (within {REPEATED_POSE_DEG:g} "
            f"deg) and add nothing about the TCP: only {distinct} distinct orientations "
            f"remain, at least {MIN_POSES} are needed; re-touch from different orientations",
            loc=("poses", pairs[0][1]),
            context={"pairs": [list(pr) for pr in pairs], "distinct_orientations": distinct},
        )
    return [
        f"touches {shown}{more} repeat an orientation (within {REPEATED_POSE_DEG:g} deg): "
        "they average noise but add nothing to the spread"
    ]


@dataclass(frozen=True)
class Block:
    ratio: float  # s_min / s_max of the centred TCP block [R_i - mean(R)]
    weakest: FloatArray  # its weakest direction, flange frame
    design_condition: float  # s_max / s_min of the stacked design matrix [R_i  -I]


def block_conditioning(R: FloatArray) -> Block:
    """Conditioning of the TCP block and of the stacked design matrix A for rotations (m, 3, 3).

    C^T C = m (I - R_bar^T R_bar) for the centred block C, and A^T A has eigenvalues
    m (1 +- s_k(R_bar)), so both follow from one 3x3 eigen-decomposition.
    """
    m = R.shape[0]
    Cs = (R - R.mean(axis=0)).reshape(-1, 3)
    evals, evecs = np.linalg.eigh(Cs.T @ Cs)
    top = float(evals[-1])
    low = max(float(evals[0]), 0.0)
    ratio = math.sqrt(low / top) if top > 0.0 else 0.0
    x = min(low / m, 1.0)  # 1 - rho^2, rho = largest singular value of R_bar
    rho = math.sqrt(1.0 - x)
    one_minus_rho = x / (1.0 + rho)
    cond = math.sqrt((1.0 + rho) / one_minus_rho) if one_minus_rho > 1e-30 else 1e15
    return Block(
        ratio=ratio, weakest=_canonical_direction(evecs[:, 0]), design_condition=min(cond, 1e15)
    )


def _canonical_direction(v: FloatArray) -> FloatArray:
    u = np.asarray(v, dtype=np.float64) / float(np.linalg.norm(v))
    if u[int(np.argmax(np.abs(u)))] < 0:
        u = -u
    return u + 0.0  # no negative zeros in messages


def check_degenerate(block: Block, *, context: str) -> None:
    if block.ratio < DEGENERACY_RATIO:
        raise InvalidInput(
            "degenerate-poses",
            f"{context}the touches rotate (almost) about one common axis, so the TCP along the "
            f"flange direction {format_vector(block.weakest)} cannot be determined (singular "
            f"value ratio {block.ratio:.1e}): add a touch rotated about a different axis",
            loc=("poses",),
            context={
                "direction_flange": [float(x) for x in block.weakest],
                "singular_value_ratio": block.ratio,
            },
        )
