"""The touch noise and the uncertainty of an N-point fit: moment and REML estimates of s_p^2, the
covariance of (t, p), the Kenward-Roger small-sample correction, and the warnings when the
residuals contradict the noise model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.arrays import FloatArray
from app.solvers.distributions import chi2_ppf
from app.solvers.npoint.model import (
    RESIDUAL_FLOOR_MM,
    Fit,
    Noise,
    lever_directions,
    mahalanobis_sq,
    noise_cov,
)
from app.solvers.quality import (
    ellipsoid95_scale,
)

#: REML iteration for the touch noise: relative tolerance on s_p^2, and its floor relative to
#: the orientation share c = (s_th |t|)^2 (a weight, never an estimate of 0 divided by)
REML_RTOL = 1e-6
_REML_FLOOR_REL = 1e-8
#: From this many touches on, correlated residuals of consecutive touches are flagged.
SERIAL_MIN_POSES = 30
SERIAL_CORRELATION_WARN = 0.5
#: Below this many residual degrees of freedom an estimated touch noise is flagged as soft.
FEW_DOF = 12


@dataclass(frozen=True)
class _Spread:
    """The uncertainty of a fit: Cov(t, p) (6, 6) mm^2 and how it was obtained."""

    cov6: FloatArray
    s_p: float  # touch noise used (configured or estimated), mm
    nu: float | None  # degrees of freedom of an estimated touch noise
    dof: float | None  # degrees of freedom behind the 95 % ellipsoid
    ellipsoid_scale: float | None  # its scale when not the chi2/F default


def uncertainty(Ru: FloatArray, resu: FloatArray, fit: Fit, noise: Noise) -> _Spread:
    """Covariance of (t, p) from the used touches Ru (m, 3, 3) and their residuals (m, 3)."""
    t = fit.t
    s_p, nu = touch_noise_level(resu, Ru, t, noise, fit)
    cov6 = covariance(fit.jac, Ru, t, s_p, noise.orientation_rad)
    dof, scale = nu, None
    if fit.touch_var is not None:
        c = (noise.orientation_rad * float(np.linalg.norm(t))) ** 2
        lam6, m_dof, lam = _kenward_roger(Ru, t, fit.touch_var, c)
        cov6 = cov6 + 2.0 * lam6
        dof, scale = m_dof, ellipsoid95_scale(m_dof) / math.sqrt(lam)
    elif nu is not None and noise.orientation_rad > 0.0:
        dof = _ellipsoid_dof(nu, s_p, cov6[:3, :3], covariance(fit.jac, Ru, t, 1.0, 0.0)[:3, :3])
    return _Spread(cov6=cov6, s_p=s_p, nu=nu, dof=dof, ellipsoid_scale=scale)


#: Part of the warning given when the residuals contradict a configured touch noise (a guided
#: session is not done while it stands: its sigma rests on that noise).
NOISE_CONTRADICTED = "are larger than the configured touch noise"


def noise_warnings(
    resu: FloatArray, Ru: FloatArray, t: FloatArray, spread: _Spread, noise: Noise
) -> list[str]:
    """Say when the residuals contradict the noise model the uncertainty rests on."""
    warnings = []
    m = Ru.shape[0]
    if noise.touch_mm is not None:
        cov = noise_cov(Ru, t, spread.s_p, noise.orientation_rad)
        sse = float(mahalanobis_sq(resu, cov).sum())
        if sse > float(chi2_ppf(1.0 - 1e-3, 3 * m - 6)):
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


def _lag1_correlation(res: FloatArray) -> float:
    """Correlation of consecutive residual vectors (m, 3): sum r_i . r_i+1 / sum |r_i|^2."""
    x = res - res.mean(axis=0)
    den = float(np.sum(x * x))
    return float(np.sum(x[:-1] * x[1:]) / den) if den > 0.0 else 0.0


def estimate_touch_noise(res: FloatArray, R: FloatArray, t: FloatArray, s_th: float) -> float:
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


def touch_var_floor(c: float) -> float:
    """Smallest s_p^2 used as a weight: keeps Cov_i invertible when REML clamps s_p^2 at 0."""
    return max(RESIDUAL_FLOOR_MM**2, _REML_FLOOR_REL * c)


def reml_touch_variance(
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
    u, _ = lever_directions(R, t)
    x = theta / (theta + c)
    n1, n2, n3 = _scaled_normal_matrices(R, t, x)
    B = np.linalg.solve(n1, np.hstack([n2, n3]))
    B2, B3 = B[:, :6], B[:, 6:]
    tr_q = m * (2.0 * x + 1.0) - float(np.trace(B2))  # theta tr Q
    tr_qq = m * (2.0 * x * x + 1.0) - 2.0 * float(np.trace(B3)) + float(np.sum(B2 * B2.T))
    u_r = np.einsum("ij,ij->i", u, res)
    quad = x * x * float(np.sum(res * res)) + (1.0 - x * x) * float(u_r @ u_r)  # theta^2 r'S^-2 r
    if not (tr_qq > 0.0 and math.isfinite(quad)):
        return theta, float(max(3 * m - 6, 1))
    new = (quad + theta * (tr_qq - tr_q)) / tr_qq
    return max(new, 0.0), tr_qq


def _scaled_normal_matrices(
    R: FloatArray, t: FloatArray, x: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """theta^k sum_i A_i^T Cov_i^-k A_i = x^k K + (1 - x^k) V for k = 1, 2, 3 (each 6x6)."""
    m = R.shape[0]
    u, tn = lever_directions(R, t)
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


def touch_noise_level(
    res: FloatArray, R: FloatArray, t: FloatArray, noise: Noise, fit: Fit | None = None
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
    s_p = estimate_touch_noise(res, R, t, noise.orientation_rad)
    if noise.orientation_rad == 0.0:
        return s_p, float(dof)
    c = (noise.orientation_rad * float(np.linalg.norm(t))) ** 2
    return s_p, dof * s_p**2 / (s_p**2 + 2.0 * c / 3.0)


def covariance(
    jac: FloatArray, R: FloatArray, t: FloatArray, s_p: float, s_th: float
) -> FloatArray:
    """Cov(t, p) (6, 6) = sum_i J_i Cov_i J_i^T for an estimator with sensitivities J."""
    flat = jac.transpose(1, 0, 2).reshape(6, -1)
    if s_th == 0.0:
        cov = s_p**2 * (flat @ flat.T)
    else:
        u, tn = lever_directions(R, t)
        c = (s_th * tn) ** 2
        ju = (jac @ u[:, :, None])[:, :, 0]
        cov = (s_p**2 + c) * (flat @ flat.T) - c * (ju.T @ ju)
    out: FloatArray = 0.5 * (cov + cov.T)
    return out
