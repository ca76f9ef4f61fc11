"""XYZ N-point TCP calibration: N >= 4 touches of one fixed point from distinct orientations.

Model: R_i t + f_i = p + e_i, with R_i (3, 3) flange -> base, f_i (3,)
flange position in mm (base frame), t (3,) the TCP in the flange frame, p (3,) the touched
point in the base frame and e_i the touch error. Every estimator returns (t, p) together with
its sensitivity to the touch errors, so that each one reports the covariance it really has
under the stated noise model (touch noise sigma_p, optional orientation noise sigma_theta):

    Cov(e_i) = sigma_p^2 I + sigma_theta^2 R_i [t]x [t]x^T R_i^T

Estimators: "stacked" (one linear least squares, the maximum-likelihood estimate under
isotropic noise), "gls" (iterated weighted least squares under the full noise model),
"pairwise" (differences of consecutive touches, the textbook 4-point method), "sphere"
(the textbook algebraic sphere fit, biased, a baseline) and "robust" (default: stacked or gls on the
consistent majority of touches found by a deterministic minimal-set search).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.noise_limits import MAX_TOUCH_NOISE_MM, MIN_TOUCH_NOISE_MM
from app.solvers.npoint.checks import (
    ALGORITHMS,
    DEGENERACY_RATIO,
    MAX_ORIENTATION_NOISE_DEG,
    MIN_POSES,
    REPEATED_POSE_DEG,
    WEAK_DIRECTION_RATIO,
    Block,
    block_conditioning,
    check_degenerate,
    check_options,
    check_predicted_sigma,
    check_repeated,
    checked_touches,
    geometry_warnings,
    relative_cosines,
)
from app.solvers.npoint.estimators import ESTIMATORS
from app.solvers.npoint.model import RESIDUAL_FLOOR_MM, BoolArray, Fit, Noise, residual_vectors
from app.solvers.npoint.noise import (
    FEW_DOF,
    NOISE_CONTRADICTED,
    SERIAL_CORRELATION_WARN,
    SERIAL_MIN_POSES,
    noise_warnings,
    uncertainty,
)
from app.solvers.npoint.robust import (
    MAX_OUTLIER_FRACTION,
    MINIMAL_SETS_ENUMERATED,
    MINIMAL_SETS_SAMPLED,
    OUTLIER_ALPHA,
    SCORING_TOUCHES,
    robust,
)
from app.solvers.numbering import numbered
from app.solvers.quality import SIGMA_CONFIGURED, SIGMA_RESIDUALS, Quality, make_quality
from app.solvers.validation import MAX_ABS_MM
from app.words import Algorithm

__all__ = [
    "ALGORITHMS",
    "DEGENERACY_RATIO",
    "FEW_DOF",
    "MAX_ORIENTATION_NOISE_DEG",
    "MAX_OUTLIER_FRACTION",
    "MAX_TOUCH_NOISE_MM",
    "MINIMAL_SETS_ENUMERATED",
    "MINIMAL_SETS_SAMPLED",
    "MIN_POSES",
    "MIN_TOUCH_NOISE_MM",
    "NOISE_CONTRADICTED",
    "OUTLIER_ALPHA",
    "REPEATED_POSE_DEG",
    "RESIDUAL_FLOOR_MM",
    "SCORING_TOUCHES",
    "SERIAL_CORRELATION_WARN",
    "SERIAL_MIN_POSES",
    "WEAK_DIRECTION_RATIO",
    "BoolArray",
    "NPointResult",
    "solve_npoint",
]


@dataclass(frozen=True)
class NPointResult:
    """TCP t (3,) mm in the flange frame, pivot p (3,) mm in the base frame, with quality."""

    algorithm: Algorithm
    tcp_mm: FloatArray
    pivot_mm: FloatArray
    pivot_covariance_mm2: FloatArray
    quality: Quality


def solve_npoint(
    rotations: ArrayLike,
    positions_mm: ArrayLike,
    *,
    algorithm: Algorithm = "robust",
    touch_noise_mm: float | None = None,
    orientation_noise_deg: float | None = None,
    max_tcp_sigma_mm: float | None = None,
) -> NPointResult:
    """Solve the TCP from N touches: rotations (N, 3, 3) flange->base, positions_mm (N, 3).

    touch_noise_mm: the tool's 1-sigma touch error per axis (mm); None: estimated from the
    residuals. orientation_noise_deg: 1-sigma flange orientation error per axis (deg); used
    as a weight model by "gls" and "robust". max_tcp_sigma_mm: refuse ("insufficient-spread")
    when the predicted TCP 1-sigma along its weakest direction exceeds it.
    Raises InvalidInput for input that cannot give a trustworthy TCP.
    """
    R, f = checked_touches(rotations, positions_mm)
    noise = check_options(algorithm, touch_noise_mm, orientation_noise_deg, max_tcp_sigma_mm)
    cosines = relative_cosines(R)
    warnings = check_repeated(cosines)
    block = block_conditioning(R)
    check_degenerate(block, context="")

    fit, used, block, fit_warnings = _fit(R, f, algorithm, noise, block)
    res_vec = residual_vectors(R, f, fit.t, fit.p)
    spread = uncertainty(R[used], res_vec[used], fit, noise)
    warnings += fit_warnings
    warnings += noise_warnings(res_vec[used], R[used], fit.t, spread, noise)
    warnings += geometry_warnings(block, algorithm)
    cov_t = spread.cov6[:3, :3]
    if max_tcp_sigma_mm is not None:
        check_predicted_sigma(cov_t, max_tcp_sigma_mm, spread.s_p, noise)

    quality = make_quality(
        residuals_mm=np.linalg.norm(res_vec, axis=1),
        used=used,
        tcp_covariance_mm2=cov_t,
        sigma_source=SIGMA_CONFIGURED if noise.touch_mm is not None else SIGMA_RESIDUALS,
        orientation_spread_deg=math.degrees(math.acos(float(np.clip(cosines.min(), -1.0, 1.0)))),
        condition_number=block.design_condition,
        outliers=tuple(int(i) for i in np.flatnonzero(~used)),
        warnings=tuple(warnings),
        dof=spread.dof,
        ellipsoid_scale=spread.ellipsoid_scale,
    )
    cov_p = spread.cov6[3:, 3:]
    return NPointResult(
        algorithm=algorithm,
        tcp_mm=np.array(fit.t, dtype=np.float64),
        pivot_mm=np.array(fit.p, dtype=np.float64),
        pivot_covariance_mm2=np.array(0.5 * (cov_p + cov_p.T), dtype=np.float64),
        quality=quality,
    )


def _fit(
    R: FloatArray, f: FloatArray, algorithm: Algorithm, noise: Noise, block: Block
) -> tuple[Fit, BoolArray, Block, list[str]]:
    """Run the estimator: the fit, the touches it used, their conditioning and its warnings.

    The robust fit may set touches aside; the remaining ones must still determine the TCP.
    """
    used: BoolArray = np.ones(R.shape[0], dtype=bool)
    warnings: list[str] = []
    if algorithm == "robust":
        fit, used, warnings = robust(R, f, noise)
        if not used.all():
            rejected = numbered("touch", np.flatnonzero(~used))
            block = block_conditioning(R[used])
            check_degenerate(block, context=f"after setting aside the missed {rejected}, ")
    else:
        fit = ESTIMATORS[algorithm](R, f, noise)
    if (
        not (np.isfinite(fit.t).all() and np.isfinite(fit.p).all())
        or max(float(np.abs(fit.t).max()), float(np.abs(fit.p).max())) > MAX_ABS_MM
    ):
        raise InvalidInput(
            "degenerate-poses",
            "the touches do not determine the TCP (the solution is unbounded); "
            "add touches rotated about different axes",
            loc=("poses",),
        )
    return fit, used, block, warnings
