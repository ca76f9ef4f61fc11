"""The robust N-point fit: a deterministic minimal-set search for the consistent majority of
touches, then refit and re-test to a fixed point.
"""

from __future__ import annotations

import itertools
import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from app.arrays import FloatArray
from app.solvers.distributions import chi2_ppf, f_ppf
from app.solvers.npoint.checks import MIN_POSES
from app.solvers.npoint.estimators import base_fit
from app.solvers.npoint.model import (
    RESIDUAL_FLOOR_MM,
    BoolArray,
    Fit,
    Noise,
    mahalanobis_sq,
    noise_cov,
    residual_vectors,
)
from app.solvers.npoint.noise import covariance, touch_noise_level
from app.solvers.numbering import number

#: The robust fit assumes at most this fraction of touches missed the point.
MAX_OUTLIER_FRACTION = 0.4
#: Family-wise false-alarm probability of the outlier test over all touches of one solve.
OUTLIER_ALPHA = 0.01
#: Enumerate every 3-touch minimal set up to this many; above it draw this many, seeded.
MINIMAL_SETS_ENUMERATED = 2000
MINIMAL_SETS_SAMPLED = 200
#: Hypotheses are scored on at most this many touches (evenly spaced) when N is larger.
SCORING_TOUCHES = 100
_MINIMAL_SET_SEED = 0x7C9C41
_MAX_REFINE_STEPS = 25
#: Degrees of freedom from which an F test is taken as chi2.
_CHI2_DOF = 10**6


@lru_cache(maxsize=512)
def _outlier_threshold(n: int, dof: int | None) -> float:
    """Squared Mahalanobis bound for one touch: Bonferroni over n touches at OUTLIER_ALPHA."""
    q = 1.0 - OUTLIER_ALPHA / n
    if dof is None:
        return float(chi2_ppf(q, 3))
    return float(3.0 * f_ppf(q, 3, max(dof, 1)))


@lru_cache(maxsize=512)
def _sse_threshold(dof: int) -> float:
    return float(chi2_ppf(1.0 - OUTLIER_ALPHA, dof))


def _touch_distances(
    R: FloatArray, f: FloatArray, used: BoolArray, fit: Fit, noise: Noise
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
    res = residual_vectors(R, f, fit.t, fit.p)
    s_p, nu = touch_noise_level(res[used], Ru, fit.t, noise, fit)
    s_th = noise.orientation_rad
    cov6 = covariance(fit.jac, Ru, fit.t, s_p, s_th)
    sign = np.where(used, -1.0, 1.0)[:, None, None]
    V = (
        noise_cov(R, fit.t, s_p, s_th)
        + sign * _predicted_cov(R, cov6)
        + RESIDUAL_FLOOR_MM**2 * np.eye(3)
    )
    if nu is None or fit.touch_var is None:
        limit = _outlier_threshold(n, None if nu is None else 3 * Ru.shape[0] - 6)
        return mahalanobis_sq(res, V) / limit, nu is not None
    evals, evecs = np.linalg.eigh(V)
    evals = np.maximum(evals, RESIDUAL_FLOOR_MM**2)
    z2 = np.einsum("nij,ni->nj", evecs, res) ** 2 / evals
    # s_p^2 dV_i / d(s_p^2) along each eigen-direction: the touch noise of the touch itself
    # and, through the fit, of the others (Cov = s_p^2 J J^T + orientation part)
    dV = np.eye(3) + sign * _predicted_cov(R, covariance(fit.jac, Ru, fit.t, 1.0, 0.0))
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
        return float(chi2_ppf(q, 1))
    return float(f_ppf(q, 1, dof))


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


def robust(R: FloatArray, f: FloatArray, noise: Noise) -> tuple[Fit, BoolArray, list[str]]:
    """Fit on the consistent majority: minimal-set search, then refit and re-test to a fixed point.

    1. With a configured touch noise, the plain fit is kept when every touch passes the test
       (fast path). 2. Every 3-touch minimal set (or a fixed seeded sample of 500) gives a
       hypothesis; the one whose h-th smallest touch distance is least wins (least median of
       squares with h = 60 % of the touches, at least 4). 3. Its h closest touches are refitted;
       touches whose Mahalanobis distance from the fit passes a Bonferroni test at 1 % are kept,
       the fit is repeated on them until the set no longer changes.
    """
    n = R.shape[0]
    if n < 5 or noise.touch_mm is not None:
        kept = _plain_fit_if_consistent(R, f, noise)
        if kept is not None:
            return kept
    h = min(n, max(MIN_POSES, math.ceil((1.0 - MAX_OUTLIER_FRACTION) * n)))
    fit, used = _refit_to_fixed_point(R, f, noise, _least_median_start(R, f, h), h)
    return fit, used, _set_aside_warnings(R, f, fit, used)


def _plain_fit_if_consistent(
    R: FloatArray, f: FloatArray, noise: Noise
) -> tuple[Fit, BoolArray, list[str]] | None:
    """The fit on every touch when they all pass the test (or when fewer than 5 cannot single
    out a miss, with a warning); None when the minimal-set search must run."""
    n = R.shape[0]
    everyone: BoolArray = np.ones(n, dtype=bool)
    fit = base_fit(R, f, noise)
    score, estimated = _touch_distances(R, f, everyone, fit, noise)
    consistent = estimated or float(score.max()) <= 1.0
    if noise.touch_mm is not None and consistent:
        res = residual_vectors(R, f, fit.t, fit.p)
        cov = noise_cov(R, fit.t, noise.touch_mm, noise.orientation_rad)
        consistent = float(mahalanobis_sq(res, cov).sum()) <= _sse_threshold(3 * n - 6)
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
    return None


def _least_median_start(R: FloatArray, f: FloatArray, h: int) -> BoolArray:
    """The h touches closest to the minimal-set hypothesis whose h-th smallest touch distance
    (on at most SCORING_TOUCHES evenly spaced touches) is least; all touches when no minimal
    set is well posed."""
    n = R.shape[0]
    ht, hp = _minimal_set_hypotheses(R, f)
    used: BoolArray = np.zeros(n, dtype=bool)
    if ht.shape[0] == 0:
        used[:] = True
        return used
    pick = np.unique(np.linspace(0, n - 1, min(n, SCORING_TOUCHES)).round().astype(np.intp))
    k = pick.size
    hk = min(k, max(MIN_POSES, math.ceil((1.0 - MAX_OUTLIER_FRACTION) * k)))
    Rt = (R[pick].reshape(-1, 3) @ ht.T).reshape(k, 3, -1)
    diff = Rt + (f[pick][:, :, None] - hp.T[None, :, :])
    dist = np.sqrt((diff * diff).sum(axis=1))  # (k, K)
    score = np.partition(dist, hk - 1, axis=0)[hk - 1]
    best = int(np.argmin(score))
    closest = np.linalg.norm(residual_vectors(R, f, ht[best], hp[best]), axis=1)
    used[np.argsort(closest, kind="stable")[:h]] = True
    return used


def _refit_to_fixed_point(
    R: FloatArray, f: FloatArray, noise: Noise, used: BoolArray, h: int
) -> tuple[Fit, BoolArray]:
    """Refit on `used` and keep the touches that pass the test (at least the h closest) until
    the set no longer changes: the fit and the touches it rests on."""
    n = R.shape[0]
    fits: dict[bytes, Fit] = {}
    for _ in range(_MAX_REFINE_STEPS):
        key = used.tobytes()
        if key not in fits:
            fits[key] = base_fit(R[used], f[used], noise)
        score, _ = _touch_distances(R, f, used, fits[key], noise)
        new = score <= 1.0
        if int(new.sum()) < h:
            new = np.zeros(n, dtype=bool)
            new[np.argsort(score, kind="stable")[:h]] = True
        if np.array_equal(new, used):
            break
        used = new
    key = used.tobytes()
    return (fits[key] if key in fits else base_fit(R[used], f[used], noise)), used


def _set_aside_warnings(R: FloatArray, f: FloatArray, fit: Fit, used: BoolArray) -> list[str]:
    """Name the touches the robust fit set aside, with how far each misses the point."""
    if used.all():
        return []
    res = np.linalg.norm(residual_vectors(R, f, fit.t, fit.p), axis=1)
    rejected = np.flatnonzero(~used)
    listed = ", ".join(f"touch {number(i)} ({res[i]:.2f} mm)" for i in rejected[:20])
    more = f" and {rejected.size - 20} more" if rejected.size > 20 else ""
    return [
        f"set aside {rejected.size} of {R.shape[0]} touches that miss the common point: "
        f"{listed}{more}"
    ]
