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

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2
from scipy.stats import f as f_dist

from app.errors import InvalidInput
from app.solvers.numbering import number, numbered
from app.solvers.quality import (
    SIGMA_CONFIGURED,
    SIGMA_RESIDUALS,
    Quality,
    ellipsoid95_scale,
    format_vector,
    make_quality,
)
from app.solvers.validation import MAX_ABS_MM, check_positions_mm, check_rotation_matrices

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

ALGORITHMS = ("robust", "stacked", "pairwise", "sphere", "gls")

#: Fewest touches the method accepts (the "XYZ 4-point" method of the pendants).
MIN_POSES = 4
#: Two touches whose orientations differ by less than this (deg) count as one orientation.
REPEATED_POSE_DEG = 0.5
#: Refuse when s_min / s_max of the centred TCP block [R_i - mean(R)] is below this: the TCP
#: component along the weakest direction is then at least 100x worse determined than the best.
DEGENERACY_RATIO = 1e-2
#: Warn (but solve) when that ratio is below this.
WEAK_DIRECTION_RATIO = 0.1
#: The robust fit assumes at most this fraction of touches missed the point.
MAX_OUTLIER_FRACTION = 0.4
#: Family-wise false-alarm probability of the outlier test over all touches of one solve.
OUTLIER_ALPHA = 0.01
#: Residuals below this (mm) are never evidence of a missed touch (rounding on exact data).
RESIDUAL_FLOOR_MM = 1e-6
#: Enumerate every 3-touch minimal set up to this many; above it draw this many, seeded.
MINIMAL_SETS_ENUMERATED = 2000
MINIMAL_SETS_SAMPLED = 200
#: Hypotheses are scored on at most this many touches (evenly spaced) when N is larger.
SCORING_TOUCHES = 100
_MINIMAL_SET_SEED = 0x7C9C41
_MAX_REFINE_STEPS = 25
_MAX_GLS_STEPS = 30
#: REML iteration for the touch noise: relative tolerance on s_p^2, and its floor relative to
#: the orientation share c = (s_th |t|)^2 (a weight, never an estimate of 0 divided by)
_REML_RTOL = 1e-6
_REML_FLOOR_REL = 1e-8
#: Degrees of freedom from which an F test is taken as chi2.
_CHI2_DOF = 10**6
#: Upper bounds on the noise options, to catch unit mistakes (m for mm, rad for deg).
MAX_TOUCH_NOISE_MM = 100.0
#: Below this (mm) a noise figure is no measurement, and its square vanishes in the weights.
MIN_TOUCH_NOISE_MM = 1e-6
MAX_ORIENTATION_NOISE_DEG = 10.0
#: From this many touches on, correlated residuals of consecutive touches are flagged.
SERIAL_MIN_POSES = 30
SERIAL_CORRELATION_WARN = 0.5
#: Below this many residual degrees of freedom an estimated touch noise is flagged as soft.
FEW_DOF = 12


@dataclass(frozen=True)
class NPointResult:
    """TCP t (3,) mm in the flange frame, pivot p (3,) mm in the base frame, with quality."""

    algorithm: str
    tcp_mm: FloatArray
    pivot_mm: FloatArray
    pivot_covariance_mm2: FloatArray
    quality: Quality


@dataclass(frozen=True)
class _Noise:
    touch_mm: float | None
    orientation_rad: float


@dataclass(frozen=True)
class _Fit:
    t: FloatArray  # (3,)
    p: FloatArray  # (3,)
    jac: FloatArray  # (m, 6, 3): d(t, p) / d(e_i), e_i the touch error of touch i
    #: s_p^2 (mm^2) estimated by REML inside the fit (gls with the touch noise unknown and an
    #: orientation noise given) and its effective degrees of freedom 2 s_p^4 / Var(s_p^2)
    touch_var: float | None = None
    touch_var_dof: float | None = None


def solve_npoint(
    rotations: ArrayLike,
    positions_mm: ArrayLike,
    *,
    algorithm: str = "robust",
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
    R, f = _checked_touches(rotations, positions_mm)
    noise = _check_options(algorithm, touch_noise_mm, orientation_noise_deg, max_tcp_sigma_mm)
    cosines = _relative_cosines(R)
    warnings = _check_repeated(cosines)
    block = _block_conditioning(R)
    _check_degenerate(block, context="")

    fit, used, block, fit_warnings = _fit(R, f, algorithm, noise, block)
    res_vec = _residual_vectors(R, f, fit.t, fit.p)
    spread = _uncertainty(R[used], res_vec[used], fit, noise)
    warnings += fit_warnings
    warnings += _noise_warnings(res_vec[used], R[used], fit.t, spread, noise)
    warnings += _geometry_warnings(block, algorithm)
    cov_t = spread.cov6[:3, :3]
    if max_tcp_sigma_mm is not None:
        _check_predicted_sigma(cov_t, max_tcp_sigma_mm, spread.s_p, noise)

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


def _checked_touches(
    rotations: ArrayLike, positions_mm: ArrayLike
) -> tuple[FloatArray, FloatArray]:
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


def _fit(
    R: FloatArray, f: FloatArray, algorithm: str, noise: _Noise, block: _Block
) -> tuple[_Fit, BoolArray, _Block, list[str]]:
    """Run the estimator: the fit, the touches it used, their conditioning and its warnings.

    The robust fit may set touches aside; the remaining ones must still determine the TCP.
    """
    used: BoolArray = np.ones(R.shape[0], dtype=bool)
    warnings: list[str] = []
    if algorithm == "robust":
        fit, used, warnings = _robust(R, f, noise)
        if not used.all():
            rejected = numbered("touch", np.flatnonzero(~used))
            block = _block_conditioning(R[used])
            _check_degenerate(block, context=f"after setting aside the missed {rejected}, ")
    else:
        fit = _ESTIMATORS[algorithm](R, f, noise)
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


@dataclass(frozen=True)
class _Spread:
    """The uncertainty of a fit: Cov(t, p) (6, 6) mm^2 and how it was obtained."""

    cov6: FloatArray
    s_p: float  # touch noise used (configured or estimated), mm
    nu: float | None  # degrees of freedom of an estimated touch noise
    dof: float | None  # degrees of freedom behind the 95 % ellipsoid
    ellipsoid_scale: float | None  # its scale when not the chi2/F default


def _uncertainty(Ru: FloatArray, resu: FloatArray, fit: _Fit, noise: _Noise) -> _Spread:
    """Covariance of (t, p) from the used touches Ru (m, 3, 3) and their residuals (m, 3)."""
    t = fit.t
    s_p, nu = _touch_noise_level(resu, Ru, t, noise, fit)
    cov6 = _covariance(fit.jac, Ru, t, s_p, noise.orientation_rad)
    dof, scale = nu, None
    if fit.touch_var is not None:
        c = (noise.orientation_rad * float(np.linalg.norm(t))) ** 2
        lam6, m_dof, lam = _kenward_roger(Ru, t, fit.touch_var, c)
        cov6 = cov6 + 2.0 * lam6
        dof, scale = m_dof, ellipsoid95_scale(m_dof) / math.sqrt(lam)
    elif nu is not None and noise.orientation_rad > 0.0:
        dof = _ellipsoid_dof(nu, s_p, cov6[:3, :3], _covariance(fit.jac, Ru, t, 1.0, 0.0)[:3, :3])
    return _Spread(cov6=cov6, s_p=s_p, nu=nu, dof=dof, ellipsoid_scale=scale)


#: Part of the warning given when the residuals contradict a configured touch noise (a guided
#: session is not done while it stands: its sigma rests on that noise).
NOISE_CONTRADICTED = "are larger than the configured touch noise"


def _noise_warnings(
    resu: FloatArray, Ru: FloatArray, t: FloatArray, spread: _Spread, noise: _Noise
) -> list[str]:
    """Say when the residuals contradict the noise model the uncertainty rests on."""
    warnings = []
    m = Ru.shape[0]
    if noise.touch_mm is not None:
        cov = _noise_cov(Ru, t, spread.s_p, noise.orientation_rad)
        sse = float(_mahalanobis_sq(resu, cov).sum())
        if sse > float(chi2.ppf(1.0 - 1e-3, 3 * m - 6)):
            rms = float(np.sqrt(np.mean(np.sum(resu**2, axis=1))))
            warnings.append(
                f"the residuals (rms {rms:.3f} mm) {NOISE_CONTRADICTED} of "
                f"{noise.touch_mm:g} mm explains: the reported uncertainty is probably optimistic"
            )
    elif spread.nu is not None and spread.nu < FEW_DOF:
        warnings.append(
            f"the touch noise was estimated from only {spread.nu:.0f} degrees of freedom; "
            "configure the tool's touch noise (or add touches) for a firmer uncertainty"
        )
    if m >= SERIAL_MIN_POSES:
        lag1 = _lag1_correlation(resu)
        if lag1 > SERIAL_CORRELATION_WARN:
            warnings.append(
                f"the residuals of consecutive touches are correlated (lag-1 correlation "
                f"{lag1:.2f}), as in a tracker stream: the uncertainty assumes independent "
                "touches and is too small; use frames further apart in time"
            )
    return warnings


def _geometry_warnings(block: _Block, algorithm: str) -> list[str]:
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


def _check_predicted_sigma(
    cov_t: FloatArray, max_tcp_sigma_mm: float, s_p: float, noise: _Noise
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


def _ellipsoid_dof(nu: float, s_p: float, cov_t: FloatArray, touch_part: FloatArray) -> float:
    """Satterthwaite degrees of freedom of the TCP ellipsoid when only s_p^2 is estimated.

    Cov_t = s_p^2 M_p + (known orientation part); an error d(s_p^2) changes the Mahalanobis
    metric by the relative amount w d(s_p^2) / s_p^2 on average over directions, with
    w = s_p^2 tr(Cov_t^-1 M_p) / 3 the touch-noise share of Cov_t (1 without orientation
    noise). s_p^2 has nu dof, so the scale of Cov_t has nu / w^2 (chi2-like when w is small).
    """
    try:
        w = s_p**2 * float(np.trace(np.linalg.solve(cov_t, touch_part))) / 3.0
    except np.linalg.LinAlgError:
        return nu
    if not math.isfinite(w) or w <= 0.0:
        return nu
    return float(min(nu / min(w * w, 1.0), 1e9))


# --------------------------------------------------------------------------- input checks


def _lag1_correlation(res: FloatArray) -> float:
    """Correlation of consecutive residual vectors (m, 3): sum r_i . r_i+1 / sum |r_i|^2."""
    x = res - res.mean(axis=0)
    den = float(np.sum(x * x))
    return float(np.sum(x[:-1] * x[1:]) / den) if den > 0.0 else 0.0


def _check_options(
    algorithm: str,
    touch_noise_mm: float | None,
    orientation_noise_deg: float | None,
    max_tcp_sigma_mm: float | None,
) -> _Noise:
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
    return _Noise(
        touch_mm=None if touch_noise_mm is None else float(touch_noise_mm),
        orientation_rad=math.radians(float(orientation_noise_deg or 0.0)),
    )


def _relative_cosines(R: FloatArray) -> FloatArray:
    """(N, N) cosine of the rotation angle between every pair: (trace(R_i^T R_j) - 1) / 2."""
    flat = R.reshape(R.shape[0], 9)
    out: FloatArray = 0.5 * (flat @ flat.T - 1.0)
    return out


def _check_repeated(cosines: FloatArray) -> list[str]:
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
class _Block:
    ratio: float  # s_min / s_max of the centred TCP block [R_i - mean(R)]
    weakest: FloatArray  # its weakest direction, flange frame
    design_condition: float  # s_max / s_min of the stacked design matrix [R_i  -I]


def _block_conditioning(R: FloatArray) -> _Block:
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
    return _Block(
        ratio=ratio, weakest=_canonical_direction(evecs[:, 0]), design_condition=min(cond, 1e15)
    )


def _canonical_direction(v: FloatArray) -> FloatArray:
    u = np.asarray(v, dtype=np.float64) / float(np.linalg.norm(v))
    if u[int(np.argmax(np.abs(u)))] < 0:
        u = -u
    return u + 0.0  # no negative zeros in messages


def _check_degenerate(block: _Block, *, context: str) -> None:
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


# ------------------------------------------------------------------------------ the model


def _rotate(R: FloatArray, t: FloatArray) -> FloatArray:
    out: FloatArray = R @ t
    return out


def _residual_vectors(R: FloatArray, f: FloatArray, t: FloatArray, p: FloatArray) -> FloatArray:
    return _rotate(R, t) + f - p


def _design(R: FloatArray) -> FloatArray:
    """The (m, 3, 6) blocks [R_i  -I] of the stacked design matrix A."""
    m = R.shape[0]
    return np.concatenate([R, np.broadcast_to(-np.eye(3), (m, 3, 3))], axis=2)


def _lever_directions(R: FloatArray, t: FloatArray) -> tuple[FloatArray, float]:
    """Unit vectors R_i t / |t| (m, 3) and |t| (mm)."""
    tn = float(np.linalg.norm(t))
    if tn == 0.0:
        return np.zeros((R.shape[0], 3)), 0.0
    return _rotate(R, t) / tn, tn


def _noise_cov(R: FloatArray, t: FloatArray, s_p: float, s_th: float) -> FloatArray:
    """Per-touch error covariance (m, 3, 3): s_p^2 I + s_th^2 R_i [t]x [t]x^T R_i^T."""
    if s_th == 0.0:
        return np.broadcast_to(s_p**2 * np.eye(3), R.shape)
    u, tn = _lever_directions(R, t)
    c = (s_th * tn) ** 2
    uu = u[:, :, None] * u[:, None, :]
    cov: FloatArray = (s_p**2 + c) * np.eye(3) - c * uu
    return cov


def _whiteners(R: FloatArray, t: FloatArray, s_p: float, s_th: float) -> FloatArray:
    """Cov_i^(-1/2) (m, 3, 3); Cov_i has eigenvalue s_p^2 along R_i t, s_p^2 + c across."""
    u, tn = _lever_directions(R, t)
    c = (s_th * tn) ** 2
    uu = u[:, :, None] * u[:, None, :]
    a = 1.0 / math.sqrt(s_p**2 + c)
    w: FloatArray = a * np.eye(3) + (1.0 / s_p - a) * uu
    return w


def _mahalanobis_sq(res: FloatArray, cov: FloatArray) -> FloatArray:
    """r_i^T cov_i^-1 r_i for residuals (m, 3) and covariances (m, 3, 3)."""
    sol = np.linalg.solve(cov, res[:, :, None])[:, :, 0]
    out: FloatArray = (res * sol).sum(axis=1)
    return out


def _estimate_touch_noise(res: FloatArray, R: FloatArray, t: FloatArray, s_th: float) -> float:
    """Touch noise s_p (mm) from residuals (m, 3) of any estimator, s_th (rad) known.

    Moment estimate: E sum |r_i|^2 ~ (3m - 6)(s_p^2 + 2c/3) with c = (s_th |t|)^2, so
    s_p^2 = sum |r_i|^2 / (3m - 6) - 2c/3, floored at c/25. Used by the estimators that do not
    weight (stacked, pairwise, sphere) and as the starting value of the REML iteration of gls.
    Without orientation noise this is sum |r_i|^2 / (3m - 6).
    """
    nu = 3 * res.shape[0] - 6
    total = float(np.sum(res * res)) / nu
    if s_th == 0.0:
        return math.sqrt(total)
    c = (s_th * float(np.linalg.norm(t))) ** 2
    return math.sqrt(max(total - 2.0 * c / 3.0, c / 25.0, RESIDUAL_FLOOR_MM**2))


def _touch_var_floor(c: float) -> float:
    """Smallest s_p^2 used as a weight: keeps Cov_i invertible when REML clamps s_p^2 at 0."""
    return max(RESIDUAL_FLOOR_MM**2, _REML_FLOOR_REL * c)


def _reml_touch_variance(
    R: FloatArray, t: FloatArray, res: FloatArray, theta: float, c: float
) -> tuple[float, float]:
    """One REML Fisher-scoring step for theta = s_p^2; returns (new theta >= 0, its dof).

    Per touch Cov_i = theta I + c (I - u_i u_i^T) with u_i = R_i t / |t| and c = (s_th |t|)^2
    known; `res` (m, 3) are the weighted-least-squares residuals under Cov(theta). With
    Q = S^-1 - S^-1 A (A^T S^-1 A)^-1 A^T S^-1 (S = blockdiag Cov_i) the REML score is
    (r^T S^-2 r - tr Q) / 2 and the expected information tr(Q Q) / 2, so the step
    theta + (r^T S^-2 r - tr Q) / tr(QQ) is also the iterated-MINQUE (Helmert) estimate.
    Var(theta^) = 2 / tr(QQ): the effective dof 2 theta^2 / Var is theta^2 tr(QQ).

    All traces reduce to 6x6 algebra: sum_i A_i^T S_i^-k A_i = x^k K + (1 - x^k) V after
    scaling by theta^k, with x = theta / (theta + c), K = sum A_i^T A_i and V = sum v_i v_i^T,
    v_i = A_i^T u_i = [t / |t|; -u_i]. Without orientation noise (x = 1) the step is
    sum |r_i|^2 / (3m - 6) with 3m - 6 dof, the classical estimate.
    """
    m = R.shape[0]
    u, _ = _lever_directions(R, t)
    x = theta / (theta + c)
    n1, n2, n3 = _scaled_normal_matrices(R, t, x)
    B = np.linalg.solve(n1, np.hstack([n2, n3]))
    B2, B3 = B[:, :6], B[:, 6:]
    tr_q = m * (2.0 * x + 1.0) - float(np.trace(B2))  # theta tr Q
    tr_qq = m * (2.0 * x * x + 1.0) - 2.0 * float(np.trace(B3)) + float(np.sum(B2 * B2.T))
    ur = np.einsum("ij,ij->i", u, res)
    quad = x * x * float(np.sum(res * res)) + (1.0 - x * x) * float(ur @ ur)  # theta^2 r'S^-2 r
    if not (tr_qq > 0.0 and math.isfinite(quad)):
        return theta, float(max(3 * m - 6, 1))
    new = (quad + theta * (tr_qq - tr_q)) / tr_qq
    return max(new, 0.0), tr_qq


def _scaled_normal_matrices(
    R: FloatArray, t: FloatArray, x: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """theta^k sum_i A_i^T Cov_i^-k A_i = x^k K + (1 - x^k) V for k = 1, 2, 3 (each 6x6)."""
    m = R.shape[0]
    u, tn = _lever_directions(R, t)
    S = R.sum(axis=0)
    K = np.empty((6, 6))
    K[:3, :3] = m * np.eye(3)
    K[3:, 3:] = m * np.eye(3)
    K[:3, 3:] = -S.T
    K[3:, :3] = -S
    th = t / tn if tn > 0.0 else np.zeros(3)
    us = u.sum(axis=0)
    V = np.empty((6, 6))
    V[:3, :3] = m * np.outer(th, th)
    V[:3, 3:] = -np.outer(th, us)
    V[3:, :3] = -np.outer(us, th)
    V[3:, 3:] = u.T @ u
    return x * K + (1.0 - x) * V, x * x * K + (1.0 - x * x) * V, x**3 * K + (1.0 - x**3) * V


def _kenward_roger(
    R: FloatArray, t: FloatArray, theta: float, c: float
) -> tuple[FloatArray, float, float]:
    """Small-sample correction for a GLS fit whose weights use the REML estimate theta = s_p^2.

    Kenward & Roger (1997) for one variance component (dCov_i / dtheta = I): returns
    (Lambda, m, lam). The covariance of (t, p) is Phi + 2 Lambda, Phi the plug-in GLS
    covariance and Lambda = Var(theta^) Phi (Q - P Phi P) Phi with P = sum A_i^T Cov_i^-2 A_i,
    Q = sum A_i^T Cov_i^-3 A_i (Kackar-Harville: the extra spread from estimated weights, and
    the bias of Phi(theta^)). For the 3-D TCP block, lam F ~ F(3, m) with
    F = e^T (Phi + 2 Lambda)_tt^-1 e / 3, so the 95 % ellipsoid is k^2 = 3 F(3, m)(0.95) / lam.
    """
    x = theta / (theta + c)
    n1, n2, n3 = _scaled_normal_matrices(R, t, x)
    g = np.linalg.inv(n1)  # Phi / theta
    b2 = g @ n2
    tr_qq = (
        R.shape[0] * (2.0 * x * x + 1.0) - 2.0 * float(np.trace(g @ n3)) + float(np.sum(b2 * b2.T))
    )  # theta^2 tr(QQ); Var(theta^) = 2 theta^2 / tr_qq
    lam6 = (2.0 * theta / tr_qq) * (g @ (n3 - n2 @ b2) @ g)
    d = b2 @ g  # Phi P Phi / theta^0 (= dPhi / dtheta)
    mt = np.linalg.solve(g[:3, :3], d[:3, :3])  # theta Phi_tt^-1 (Phi P Phi)_tt
    ell = 3.0
    a1 = 2.0 * float(np.trace(mt)) ** 2 / tr_qq
    a2 = 2.0 * float(np.sum(mt * mt.T)) / tr_qq
    big_b = (a1 + 6.0 * a2) / (2.0 * ell)
    gg = ((ell + 1.0) * a1 - (ell + 4.0) * a2) / ((ell + 2.0) * a2)
    den = 3.0 * ell + 2.0 * (1.0 - gg)
    c1, c2, c3 = gg / den, (ell - gg) / den, (ell + 2.0 - gg) / den
    e_star = 1.0 / (1.0 - a2 / ell)
    v_star = (2.0 / ell) * (1.0 + c1 * big_b) / ((1.0 - c2 * big_b) ** 2 * (1.0 - c3 * big_b))
    rho = v_star / (2.0 * e_star**2)
    m_dof = 4.0 + (ell + 2.0) / (ell * rho - 1.0) if ell * rho > 1.0 else 1e9
    lam = m_dof / (e_star * (m_dof - 2.0))
    return lam6, m_dof, lam


def _touch_noise_level(
    res: FloatArray, R: FloatArray, t: FloatArray, noise: _Noise, fit: _Fit | None = None
) -> tuple[float, float | None]:
    """(s_p, nu): the configured touch noise and None, or the estimate and the effective dof
    2 s_p^4 / Var(s_p^2) of its square: REML's when the fit carries one, else the moment
    estimate's (3m - 6 without orientation noise, less with it: the known orientation share
    of the residuals makes the difference s_p^2 = sum |r|^2 / dof - 2c/3 less certain).
    """
    if noise.touch_mm is not None:
        return noise.touch_mm, None
    if fit is not None and fit.touch_var is not None and fit.touch_var_dof is not None:
        return math.sqrt(fit.touch_var), fit.touch_var_dof
    dof = 3 * res.shape[0] - 6
    s_p = _estimate_touch_noise(res, R, t, noise.orientation_rad)
    if noise.orientation_rad == 0.0:
        return s_p, float(dof)
    c = (noise.orientation_rad * float(np.linalg.norm(t))) ** 2
    return s_p, dof * s_p**2 / (s_p**2 + 2.0 * c / 3.0)


def _covariance(
    jac: FloatArray, R: FloatArray, t: FloatArray, s_p: float, s_th: float
) -> FloatArray:
    """Cov(t, p) (6, 6) = sum_i J_i Cov_i J_i^T for an estimator with sensitivities J."""
    flat = jac.transpose(1, 0, 2).reshape(6, -1)
    if s_th == 0.0:
        cov = s_p**2 * (flat @ flat.T)
    else:
        u, tn = _lever_directions(R, t)
        c = (s_th * tn) ** 2
        ju = (jac @ u[:, :, None])[:, :, 0]
        cov = (s_p**2 + c) * (flat @ flat.T) - c * (ju.T @ ju)
    out: FloatArray = 0.5 * (cov + cov.T)
    return out


# ---------------------------------------------------------------------------- estimators


def _fit_stacked(R: FloatArray, f: FloatArray) -> _Fit:
    """[R_i -I][t; p] = -f_i by least squares; p eliminated: (R_i - R_bar) t = -(f_i - f_bar)."""
    m = R.shape[0]
    Rbar = R.sum(axis=0) / m
    fbar = f.sum(axis=0) / m
    C = R - Rbar
    Cs = C.reshape(-1, 3)
    t = np.linalg.lstsq(Cs, (fbar - f).reshape(-1), rcond=None)[0]
    p = Rbar @ t + fbar
    G = np.linalg.inv(Cs.T @ Cs)
    jt = -(G @ C.transpose(0, 2, 1))
    jp = Rbar @ jt + np.eye(3) / m
    return _Fit(t=t, p=p, jac=np.concatenate([jt, jp], axis=1))


def _fit_weighted(R: FloatArray, f: FloatArray, whiten: FloatArray, start: _Fit) -> _Fit:
    """Weighted least squares for [t; p] with per-touch whiteners W_i^(1/2) (m, 3, 3).

    Solved as a correction to `start` from its whitened residuals, so that strongly unequal
    weights cost precision only in proportion to the residuals (exact data stay exact).
    """
    A = _design(R)
    Aw = whiten @ A
    rw = -np.einsum("nij,nj->ni", whiten, _residual_vectors(R, f, start.t, start.p))
    Aws = Aw.reshape(-1, 6)
    delta = np.linalg.lstsq(Aws, rw.reshape(-1), rcond=None)[0]
    Finv = np.linalg.inv(Aws.T @ Aws)
    W = np.swapaxes(whiten, 1, 2) @ whiten
    jac = -(Finv @ A.transpose(0, 2, 1) @ W)
    return _Fit(t=start.t + delta[:3], p=start.p + delta[3:], jac=jac)


def _fit_gls(R: FloatArray, f: FloatArray, noise: _Noise) -> _Fit:
    """Iterated weighted least squares under the touch + orientation noise model.

    With the touch noise unknown, s_p^2 is estimated jointly by REML (restricted maximum
    likelihood, one Fisher-scoring step per reweighting): the fixed point is both the weighted
    fit for that s_p and the REML estimate of s_p given the fit's residuals. REML, unlike a
    moment estimate on weighted residuals, accounts for the 6 fitted parameters in every
    direction (the trace of Q), so it does not collapse under its own weights.
    """
    fit = _fit_stacked(R, f)
    s_th = noise.orientation_rad
    if s_th == 0.0:
        return fit  # isotropic weights: the stacked solution is the weighted one
    if noise.touch_mm is not None:
        s_p = noise.touch_mm
        for _ in range(_MAX_GLS_STEPS):
            tn = float(np.linalg.norm(fit.t))
            new = _fit_weighted(R, f, _whiteners(R, fit.t, s_p, s_th), fit)
            step = float(np.linalg.norm(new.t - fit.t))
            fit = new
            if step <= 1e-12 * (1.0 + tn):
                break
        return fit
    res = _residual_vectors(R, f, fit.t, fit.p)
    theta = _estimate_touch_noise(res, R, fit.t, s_th) ** 2
    dof = float(max(3 * R.shape[0] - 6, 1))
    last: tuple[float, float] | None = None  # previous (theta_w, REML update of it)
    for _ in range(_MAX_GLS_STEPS):
        tn = float(np.linalg.norm(fit.t))
        theta_w = max(theta, _touch_var_floor((s_th * tn) ** 2))
        new = _fit_weighted(R, f, _whiteners(R, fit.t, math.sqrt(theta_w), s_th), fit)
        res = _residual_vectors(R, f, new.t, new.p)
        update, dof = _reml_touch_variance(R, new.t, res, theta_w, (s_th * tn) ** 2)
        step = float(np.linalg.norm(new.t - fit.t))
        fit = new
        if step <= 1e-10 * (1.0 + tn) and abs(update - theta_w) <= _REML_RTOL * theta_w:
            theta = update
            break
        # the fixed point theta = update(theta) oscillates through the refit: secant step
        theta = update
        if last is not None:
            h0, h1 = last[1] - last[0], update - theta_w
            if h1 != h0 and last[0] != theta_w:
                secant = theta_w - h1 * (theta_w - last[0]) / (h1 - h0)
                if math.isfinite(secant) and secant >= 0.0:
                    theta = secant
        last = (theta_w, update)
    theta = max(theta, _touch_var_floor((s_th * float(np.linalg.norm(fit.t))) ** 2))
    return replace(fit, touch_var=theta, touch_var_dof=dof)


def _fit_pairwise(R: FloatArray, f: FloatArray) -> _Fit:
    """(R_i - R_i+1) t = -(f_i - f_i+1) over consecutive touches; then p = mean(R_i t + f_i).

    Consecutive pairs, as the textbook 4-point method pairs them: over all pairs the normal
    equations are exactly N times the stacked ones, which would make this option a copy of
    "stacked".
    """
    m = R.shape[0]
    D = R[:-1] - R[1:]
    Ds = D.reshape(-1, 3)
    t = np.linalg.lstsq(Ds, -(f[:-1] - f[1:]).reshape(-1), rcond=None)[0]
    Rbar = R.mean(axis=0)
    p = Rbar @ t + f.mean(axis=0)
    G = np.linalg.pinv(Ds.T @ Ds)
    Dt = np.swapaxes(D, 1, 2)
    coef = np.zeros((m, 3, 3))
    coef[:-1] += Dt
    coef[1:] -= Dt
    jt = -(G @ coef)
    jp = Rbar @ jt + np.eye(3) / m
    return _Fit(t=np.asarray(t, dtype=np.float64), p=p, jac=np.concatenate([jt, jp], axis=1))


def _fit_sphere(R: FloatArray, f: FloatArray) -> _Fit:
    """Algebraic sphere |f|^2 = 2 f.c + k through the flanges: p = c, t = mean R_i^T (c - f_i).

    Solved in centred, scaled coordinates (the fit is similarity-equivariant) for conditioning.
    """
    m = R.shape[0]
    fbar = f.mean(axis=0)
    g = f - fbar
    scale = float(np.sqrt(np.mean(np.sum(g**2, axis=1)))) or 1.0
    gs = g / scale
    M = np.hstack([2.0 * gs, np.ones((m, 1))])
    y = np.sum(gs**2, axis=1)
    x = np.linalg.lstsq(M, y, rcond=None)[0]
    cs = x[:3]
    c = cs * scale + fbar
    t = np.einsum("nji,nj->i", R, c - f) / m
    # d c / d f_i via the normal equations of the (scaled) fit; the map is degree-0 homogeneous
    r = y - M @ x
    Minv = np.linalg.pinv(M.T @ M)
    rhs = np.zeros((m, 4, 3))
    rhs[:, :3, :] = 2.0 * r[:, None, None] * np.eye(3)
    rhs += 2.0 * np.einsum("na,nb->nab", M, gs - cs)
    jc = np.einsum("ab,nbc->nac", Minv, rhs)[:, :3, :]
    Rbar = R.mean(axis=0)
    jt = np.einsum("ba,nbc->nac", Rbar, jc) - np.swapaxes(R, 1, 2) / m
    return _Fit(t=t, p=c, jac=np.concatenate([jt, jc], axis=1))


def _base_fit(R: FloatArray, f: FloatArray, noise: _Noise) -> _Fit:
    return _fit_gls(R, f, noise) if noise.orientation_rad > 0.0 else _fit_stacked(R, f)


_ESTIMATORS: dict[str, Callable[[FloatArray, FloatArray, _Noise], _Fit]] = {
    "stacked": lambda R, f, noise: _fit_stacked(R, f),
    "gls": _fit_gls,
    "pairwise": lambda R, f, noise: _fit_pairwise(R, f),
    "sphere": lambda R, f, noise: _fit_sphere(R, f),
}


# --------------------------------------------------------------------------------- robust


@lru_cache(maxsize=512)
def _outlier_threshold(n: int, dof: int | None) -> float:
    """Squared Mahalanobis bound for one touch: Bonferroni over n touches at OUTLIER_ALPHA."""
    q = 1.0 - OUTLIER_ALPHA / n
    if dof is None:
        return float(chi2.ppf(q, 3))
    return float(3.0 * f_dist.ppf(q, 3, max(dof, 1)))


@lru_cache(maxsize=512)
def _sse_threshold(dof: int) -> float:
    return float(chi2.ppf(1.0 - OUTLIER_ALPHA, dof))


def _touch_distances(
    R: FloatArray, f: FloatArray, used: BoolArray, fit: _Fit, noise: _Noise
) -> tuple[FloatArray, bool]:
    """Outlier score of every touch's residual from the fit on `used` (<= 1: consistent), and
    whether the touch noise behind it was estimated.

    A used touch's residual has covariance V_i = Cov_i - A_i Cov A_i^T, a left-out touch's
    Cov_i + A_i Cov A_i^T (prediction error), with Cov the (6, 6) covariance of the fit. The
    score is the squared Mahalanobis distance over its Bonferroni bound at OUTLIER_ALPHA over
    the n touches: chi2(3) with a configured noise, 3 F(3, 3m - 6) with one estimated without
    orientation noise. With orientation noise and s_p^2 estimated (nu dof) only the share
    w = s_p^2 / lambda of each eigen-direction (eigenvalue lambda) of V_i is uncertain: along
    R_i t it is nearly all (heavy F tail, few dof), across it little (known orientation noise).
    Each of the 3 directions is then tested alone against F(1, nu / w^2) at OUTLIER_ALPHA / 3n,
    so that a poorly known touch noise does not hide misses across the lever.
    """
    n = R.shape[0]
    Ru = R[used]
    res = _residual_vectors(R, f, fit.t, fit.p)
    s_p, nu = _touch_noise_level(res[used], Ru, fit.t, noise, fit)
    s_th = noise.orientation_rad
    cov6 = _covariance(fit.jac, Ru, fit.t, s_p, s_th)
    sign = np.where(used, -1.0, 1.0)[:, None, None]
    V = (
        _noise_cov(R, fit.t, s_p, s_th)
        + sign * _predicted_cov(R, cov6)
        + RESIDUAL_FLOOR_MM**2 * np.eye(3)
    )
    if nu is None or fit.touch_var is None:
        limit = _outlier_threshold(n, None if nu is None else 3 * Ru.shape[0] - 6)
        return _mahalanobis_sq(res, V) / limit, nu is not None
    evals, evecs = np.linalg.eigh(V)
    evals = np.maximum(evals, RESIDUAL_FLOOR_MM**2)
    z2 = np.einsum("nij,ni->nj", evecs, res) ** 2 / evals
    # s_p^2 dV_i / d(s_p^2) along each eigen-direction: the touch noise of the touch itself
    # and, through the fit, of the others (Cov = s_p^2 J J^T + orientation part)
    dV = np.eye(3) + sign * _predicted_cov(R, _covariance(fit.jac, Ru, fit.t, 1.0, 0.0))
    share = np.einsum("nij,nik,nkj->nj", evecs, dV, evecs)
    w = np.clip(s_p**2 * share / evals, 1e-6, 1.0)
    limits = _direction_limits(n, nu / (w * w))
    score: FloatArray = (z2 / limits).max(axis=1)
    return score, True


def _predicted_cov(R: FloatArray, cov6: FloatArray) -> FloatArray:
    """A_i Cov A_i^T (n, 3, 3) with A_i = [R_i  -I], Cov (6, 6) the covariance of (t, p)."""
    RC = R @ cov6[:3, :]  # (n, 3, 6): [R Ctt, R Ctp]
    pred = RC[:, :, :3] @ R.transpose(0, 2, 1) - RC[:, :, 3:]
    out: FloatArray = pred - cov6[3:, :3] @ R.transpose(0, 2, 1) + cov6[3:, 3:]
    return out


def _direction_limits(n: int, dof: FloatArray) -> FloatArray:
    """Bound on one direction's squared distance, F(1, dof) at OUTLIER_ALPHA / 3n (dof floored)."""
    ints = np.clip(np.floor(dof), 1, _CHI2_DOF).astype(np.int64)
    uniq, inverse = np.unique(ints, return_inverse=True)
    limits = np.array([_direction_threshold(n, int(k)) for k in uniq])
    out: FloatArray = limits[inverse].reshape(dof.shape)
    return out


@lru_cache(maxsize=4096)
def _direction_threshold(n: int, dof: int) -> float:
    q = 1.0 - OUTLIER_ALPHA / (3 * n)
    if dof >= _CHI2_DOF:
        return float(chi2.ppf(q, 1))
    return float(f_dist.ppf(q, 1, dof))


@lru_cache(maxsize=64)
def _minimal_sets(n: int) -> NDArray[np.intp]:
    """Deterministic 3-touch minimal sets: all of them, or a fixed seeded sample."""
    if math.comb(n, 3) <= MINIMAL_SETS_ENUMERATED:
        return np.array(list(itertools.combinations(range(n), 3)), dtype=np.intp)
    rng = np.random.default_rng(_MINIMAL_SET_SEED)
    draws = rng.integers(0, n, size=(3 * MINIMAL_SETS_SAMPLED, 3))
    ok = (draws[:, 0] != draws[:, 1]) & (draws[:, 0] != draws[:, 2]) & (draws[:, 1] != draws[:, 2])
    sets: NDArray[np.intp] = draws[ok][:MINIMAL_SETS_SAMPLED].astype(np.intp)
    return sets


def _minimal_set_hypotheses(R: FloatArray, f: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(t, p) solved exactly from every minimal set: (K, 3) and (K, 3), ill-posed sets dropped."""
    idx = _minimal_sets(R.shape[0])
    g = (R.transpose(0, 2, 1) @ f[:, :, None])[:, :, 0]  # R_i^T f_i
    S = R[idx].sum(axis=1)
    F = f[idx].sum(axis=1)
    G = g[idx].sum(axis=1)
    St = np.swapaxes(S, 1, 2)
    M = 3.0 * np.eye(3) - St @ S / 3.0
    rhs = (St @ F[:, :, None])[:, :, 0] / 3.0 - G
    # eigenvalues of M lie in [0, 4]; det well above 0 keeps the solve well-posed
    ok = np.linalg.det(M) > 1e-9
    if not ok.any():
        return np.zeros((0, 3)), np.zeros((0, 3))
    t = np.linalg.solve(M[ok], rhs[ok][:, :, None])[:, :, 0]
    p = ((S[ok] @ t[:, :, None])[:, :, 0] + F[ok]) / 3.0
    return t, p


def _robust(R: FloatArray, f: FloatArray, noise: _Noise) -> tuple[_Fit, BoolArray, list[str]]:
    """Fit on the consistent majority: minimal-set search, then refit and re-test to a fixed point.

    1. With a configured touch noise, the plain fit is kept when every touch passes the test
       (fast path). 2. Every 3-touch minimal set (or a fixed seeded sample of 500) gives a
       hypothesis; the one whose h-th smallest touch distance is least wins (least median of
       squares with h = 60 % of the touches, at least 4). 3. Its h closest touches are refitted;
       touches whose Mahalanobis distance from the fit passes a Bonferroni test at 1 % are kept,
       the fit is repeated on them until the set no longer changes.
    """
    n = R.shape[0]
    everyone: BoolArray = np.ones(n, dtype=bool)
    if n < 5 or noise.touch_mm is not None:
        fit = _base_fit(R, f, noise)
        score, estimated = _touch_distances(R, f, everyone, fit, noise)
        consistent = estimated or float(score.max()) <= 1.0
        if noise.touch_mm is not None and consistent:
            res = _residual_vectors(R, f, fit.t, fit.p)
            cov = _noise_cov(R, fit.t, noise.touch_mm, noise.orientation_rad)
            consistent = float(_mahalanobis_sq(res, cov).sum()) <= _sse_threshold(3 * n - 6)
        if consistent:
            return fit, everyone, []
        if n < 5:
            return (
                fit,
                everyone,
                [
                    "a touch misses the common point by more than the touch noise explains, but "
                    f"with {n} touches it cannot be singled out: add touches"
                ],
            )

    h = min(n, max(MIN_POSES, math.ceil((1.0 - MAX_OUTLIER_FRACTION) * n)))
    ht, hp = _minimal_set_hypotheses(R, f)
    used: BoolArray = np.zeros(n, dtype=bool)
    if ht.shape[0] == 0:
        used[:] = True
    else:
        pick = np.unique(np.linspace(0, n - 1, min(n, SCORING_TOUCHES)).round().astype(np.intp))
        k = pick.size
        hk = min(k, max(MIN_POSES, math.ceil((1.0 - MAX_OUTLIER_FRACTION) * k)))
        Rt = (R[pick].reshape(-1, 3) @ ht.T).reshape(k, 3, -1)
        diff = Rt + (f[pick][:, :, None] - hp.T[None, :, :])
        dist = np.sqrt((diff * diff).sum(axis=1))  # (k, K)
        score = np.partition(dist, hk - 1, axis=0)[hk - 1]
        best = int(np.argmin(score))
        closest = np.linalg.norm(_residual_vectors(R, f, ht[best], hp[best]), axis=1)
        used[np.argsort(closest, kind="stable")[:h]] = True

    fits: dict[bytes, _Fit] = {}
    for _ in range(_MAX_REFINE_STEPS):
        key = used.tobytes()
        if key not in fits:
            fits[key] = _base_fit(R[used], f[used], noise)
        score, _ = _touch_distances(R, f, used, fits[key], noise)
        new = score <= 1.0
        if int(new.sum()) < h:
            new = np.zeros(n, dtype=bool)
            new[np.argsort(score, kind="stable")[:h]] = True
        if np.array_equal(new, used):
            break
        used = new
    key = used.tobytes()
    fit = fits[key] if key in fits else _base_fit(R[used], f[used], noise)

    warnings: list[str] = []
    if not used.all():
        res = np.linalg.norm(_residual_vectors(R, f, fit.t, fit.p), axis=1)
        rejected = np.flatnonzero(~used)
        listed = ", ".join(f"touch {number(i)} ({res[i]:.2f} mm)" for i in rejected[:20])
        more = f" and {rejected.size - 20} more" if rejected.size > 20 else ""
        warnings.append(
            f"set aside {rejected.size} of {n} touches that miss the common point: {listed}{more}"
        )
    return fit, used, warnings
