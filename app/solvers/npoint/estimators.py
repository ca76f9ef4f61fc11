"""The N-point estimators: stacked, gls (with REML for an unknown touch noise), pairwise and
sphere; each returns (t, p) with its sensitivity to the touch errors.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from app.arrays import FloatArray
from app.solvers.npoint.model import Fit, Noise, design, residual_vectors, whiteners
from app.solvers.npoint.noise import (
    REML_RTOL,
    estimate_touch_noise,
    reml_touch_variance,
    touch_var_floor,
)

_MAX_GLS_STEPS = 30


def _fit_stacked(R: FloatArray, f: FloatArray) -> Fit:
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
    return Fit(t=t, p=p, jac=np.concatenate([jt, jp], axis=1))


def _fit_weighted(R: FloatArray, f: FloatArray, whiten: FloatArray, start: Fit) -> Fit:
    """Weighted least squares for [t; p] with per-touch whiteners W_i^(1/2) (m, 3, 3).

    Solved as a correction to `start` from its whitened residuals, so that strongly unequal
    weights cost precision only in proportion to the residuals (exact data stay exact).
    """
    A = design(R)
    Aw = whiten @ A
    rw = -np.einsum("nij,nj->ni", whiten, residual_vectors(R, f, start.t, start.p))
    Aws = Aw.reshape(-1, 6)
    delta = np.linalg.lstsq(Aws, rw.reshape(-1), rcond=None)[0]
    Finv = np.linalg.inv(Aws.T @ Aws)
    W = np.swapaxes(whiten, 1, 2) @ whiten
    jac = -(Finv @ A.transpose(0, 2, 1) @ W)
    return Fit(t=start.t + delta[:3], p=start.p + delta[3:], jac=jac)


def _fit_gls(R: FloatArray, f: FloatArray, noise: Noise) -> Fit:
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
            new = _fit_weighted(R, f, whiteners(R, fit.t, s_p, s_th), fit)
            step = float(np.linalg.norm(new.t - fit.t))
            fit = new
            if step <= 1e-12 * (1.0 + tn):
                break
        return fit
    res = residual_vectors(R, f, fit.t, fit.p)
    theta = estimate_touch_noise(res, R, fit.t, s_th) ** 2
    dof = float(max(3 * R.shape[0] - 6, 1))
    last: tuple[float, float] | None = None  # previous (theta_w, REML update of it)
    for _ in range(_MAX_GLS_STEPS):
        tn = float(np.linalg.norm(fit.t))
        theta_w = max(theta, touch_var_floor((s_th * tn) ** 2))
        new = _fit_weighted(R, f, whiteners(R, fit.t, math.sqrt(theta_w), s_th), fit)
        res = residual_vectors(R, f, new.t, new.p)
        update, dof = reml_touch_variance(R, new.t, res, theta_w, (s_th * tn) ** 2)
        step = float(np.linalg.norm(new.t - fit.t))
        fit = new
        if step <= 1e-10 * (1.0 + tn) and abs(update - theta_w) <= REML_RTOL * theta_w:
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
    theta = max(theta, touch_var_floor((s_th * float(np.linalg.norm(fit.t))) ** 2))
    return replace(fit, touch_var=theta, touch_var_dof=dof)


def _fit_pairwise(R: FloatArray, f: FloatArray) -> Fit:
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
    return Fit(t=np.asarray(t, dtype=np.float64), p=p, jac=np.concatenate([jt, jp], axis=1))


def _fit_sphere(R: FloatArray, f: FloatArray) -> Fit:
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
    return Fit(t=t, p=c, jac=np.concatenate([jt, jc], axis=1))


def base_fit(R: FloatArray, f: FloatArray, noise: Noise) -> Fit:
    return _fit_gls(R, f, noise) if noise.orientation_rad > 0.0 else _fit_stacked(R, f)


ESTIMATORS: dict[str, Callable[[FloatArray, FloatArray, Noise], Fit]] = {
    "stacked": lambda R, f, noise: _fit_stacked(R, f),
    "gls": _fit_gls,
    "pairwise": lambda R, f, noise: _fit_pairwise(R, f),
    "sphere": lambda R, f, noise: _fit_sphere(R, f),
}
