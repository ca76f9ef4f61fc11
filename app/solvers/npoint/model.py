"""The N-point model shared by the estimators: residuals R_i t + f_i - p, the design matrix, and the
per-touch noise covariance s_p^2 I + s_th^2 R_i [t]x [t]x^T R_i^T with its whiteners.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from app.arrays import FloatArray

BoolArray = NDArray[np.bool_]
#: Residuals below this (mm) are never evidence of a missed touch (rounding on exact data).
RESIDUAL_FLOOR_MM = 1e-6


@dataclass(frozen=True)
class Noise:
    touch_mm: float | None
    orientation_rad: float


@dataclass(frozen=True)
class Fit:
    t: FloatArray  # (3,)
    p: FloatArray  # (3,)
    jac: FloatArray  # (m, 6, 3): d(t, p) / d(e_i), e_i the touch error of touch i
    #: s_p^2 (mm^2) estimated by REML inside the fit (gls with the touch noise unknown and an
    #: orientation noise given) and its effective degrees of freedom 2 s_p^4 / Var(s_p^2)
    touch_var: float | None = None
    touch_var_dof: float | None = None


def _rotate(R: FloatArray, t: FloatArray) -> FloatArray:
    out: FloatArray = R @ t
    return out


def residual_vectors(R: FloatArray, f: FloatArray, t: FloatArray, p: FloatArray) -> FloatArray:
    return _rotate(R, t) + f - p


def design(R: FloatArray) -> FloatArray:
    """The (m, 3, 6) blocks [R_i  -I] of the stacked design matrix A."""
    m = R.shape[0]
    return np.concatenate([R, np.broadcast_to(-np.eye(3), (m, 3, 3))], axis=2)


def lever_directions(R: FloatArray, t: FloatArray) -> tuple[FloatArray, float]:
    """Unit vectors R_i t / |t| (m, 3) and |t| (mm)."""
    tn = float(np.linalg.norm(t))
    if tn == 0.0:
        return np.zeros((R.shape[0], 3)), 0.0
    return _rotate(R, t) / tn, tn


def noise_cov(R: FloatArray, t: FloatArray, s_p: float, s_th: float) -> FloatArray:
    """Per-touch error covariance (m, 3, 3): s_p^2 I + s_th^2 R_i [t]x [t]x^T R_i^T."""
    if s_th == 0.0:
        return np.broadcast_to(s_p**2 * np.eye(3), R.shape)
    u, tn = lever_directions(R, t)
    c = (s_th * tn) ** 2
    uu = u[:, :, None] * u[:, None, :]
    cov: FloatArray = (s_p**2 + c) * np.eye(3) - c * uu
    return cov


def whiteners(R: FloatArray, t: FloatArray, s_p: float, s_th: float) -> FloatArray:
    """Cov_i^(-1/2) (m, 3, 3); Cov_i has eigenvalue s_p^2 along R_i t, s_p^2 + c across."""
    u, tn = lever_directions(R, t)
    c = (s_th * tn) ** 2
    uu = u[:, :, None] * u[:, None, :]
    a = 1.0 / math.sqrt(s_p**2 + c)
    w: FloatArray = a * np.eye(3) + (1.0 / s_p - a) * uu
    return w


def mahalanobis_sq(res: FloatArray, cov: FloatArray) -> FloatArray:
    """r_i^T cov_i^-1 r_i for residuals (m, 3) and covariances (m, 3, 3)."""
    sol = np.linalg.solve(cov, res[:, :, None])[:, :, 0]
    out: FloatArray = (res * sol).sum(axis=1)
    return out
