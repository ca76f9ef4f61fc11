"""Quality of a TCP solution: residuals, propagated uncertainty, conditioning, flags.

Every solver reports a `Quality` made of plain Python floats and tuples, so that it
serialises to JSON as it is (`dataclasses.asdict`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Final, Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.solvers.distributions import chi2_ppf, f_ppf

#: Probability content of the reported uncertainty ellipsoid.
ELLIPSOID_PROBABILITY = 0.95

SigmaSource = Literal["configured", "residuals"]
SIGMA_CONFIGURED: Final = "configured"
SIGMA_RESIDUALS: Final = "residuals"


@dataclass(frozen=True)
class Quality:
    """How well a TCP is determined; lengths mm, angles deg, plain floats for JSON."""

    n_poses: int
    rms_mm: float
    max_mm: float
    residuals_mm: tuple[float, ...]
    tcp_sigma_mm: tuple[float, float, float]
    tcp_covariance_mm2: tuple[tuple[float, ...], ...]
    sigma_source: SigmaSource
    orientation_spread_deg: float
    condition_number: float
    outliers: tuple[int, ...]
    warnings: tuple[str, ...]
    ellipsoid95_scale: float


def ellipsoid95_scale(dof: float | None) -> float:
    """Factor k so that (x - x^)^T Cov^-1 (x - x^) <= k^2 holds 95 % of the time in 3-D.

    `dof` None: the covariance rests on a configured (known) noise level, k^2 = chi2_3(0.95).
    `dof` > 0: the noise level was estimated from residuals with `dof` (effective, possibly
    fractional) degrees of freedom, k^2 = 3 F(3, dof)(0.95) (Hotelling), which is wider for
    few touches. dof is rounded to 3 significant digits (the quantile moves far less).
    """
    if dof is None:
        return _scale(None)
    return _scale(float(f"{max(float(dof), 1.0):.3g}"))


@lru_cache(maxsize=1024)
def _scale(dof: float | None) -> float:
    if dof is None:
        return float(np.sqrt(chi2_ppf(ELLIPSOID_PROBABILITY, 3)))
    return float(np.sqrt(3.0 * f_ppf(ELLIPSOID_PROBABILITY, 3, dof)))


def ellipsoid_semi_axes(covariance: ArrayLike, scale: float) -> tuple[FloatArray, FloatArray]:
    """The uncertainty ellipsoid's semi-axes (3,), longest first, and their unit directions
    (3, 3), one per row: sqrt of the covariance's eigenvalues times `scale`."""
    values, vectors = np.linalg.eigh(np.asarray(covariance, dtype=float))
    order = np.argsort(values)[::-1]
    semi = scale * np.sqrt(np.clip(values[order], 0.0, None))
    return semi, vectors[:, order].T


def orientation_spread_deg(rotations: ArrayLike) -> float:
    """Largest rotation angle between any two of the (N, 3, 3) rotations, degrees."""
    arr = np.asarray(rotations, dtype=np.float64)
    if arr.shape[0] < 2:
        return 0.0
    quats = Rotation.from_matrix(arr).as_quat()
    smallest = float(np.clip(np.abs(quats @ quats.T).min(), 0.0, 1.0))
    return float(np.degrees(2.0 * np.arccos(smallest)))


def format_vector(v: ArrayLike) -> str:
    """A 3-vector as a technician reads it: "[0.00, 0.00, 1.00]"."""
    return "[" + ", ".join(f"{float(x):.2f}" for x in np.asarray(v).ravel()) + "]"


def make_quality(
    *,
    residuals_mm: ArrayLike,
    used: ArrayLike | None = None,
    tcp_covariance_mm2: ArrayLike,
    sigma_source: SigmaSource,
    orientation_spread_deg: float,
    condition_number: float,
    outliers: tuple[int, ...] = (),
    warnings: tuple[str, ...] = (),
    dof: float | None,
    ellipsoid_scale: float | None = None,
) -> Quality:
    """Build a Quality from per-touch residuals (N,) mm and the TCP covariance (3, 3) mm^2.

    rms and max are over the touches used in the fit (`used`, a boolean mask; default all):
    a rejected touch is named in `outliers` and keeps its residual in `residuals_mm`.
    `dof` is None when the noise level was configured, else the (effective) degrees of freedom
    of the estimated noise level behind the covariance. `ellipsoid_scale`, when given, replaces
    the scale that follows from `dof` (a small-sample correction such as Kenward-Roger's).
    """
    res = np.asarray(residuals_mm, dtype=np.float64).ravel()
    mask = np.ones(res.shape, dtype=bool) if used is None else np.asarray(used, dtype=bool)
    inl = res[mask] if mask.any() else res
    cov = np.asarray(tcp_covariance_mm2, dtype=np.float64).reshape(3, 3)
    cov = 0.5 * (cov + cov.T)
    sig = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return Quality(
        n_poses=int(res.size),
        rms_mm=float(np.sqrt(np.mean(inl**2))) if inl.size else 0.0,
        max_mm=float(inl.max()) if inl.size else 0.0,
        residuals_mm=tuple(float(x) for x in res),
        tcp_sigma_mm=(float(sig[0]), float(sig[1]), float(sig[2])),
        tcp_covariance_mm2=tuple(tuple(float(x) for x in row) for row in cov),
        sigma_source=sigma_source,
        orientation_spread_deg=float(orientation_spread_deg),
        condition_number=float(condition_number),
        outliers=tuple(int(i) for i in outliers),
        warnings=tuple(warnings),
        ellipsoid95_scale=ellipsoid95_scale(dof) if ellipsoid_scale is None else ellipsoid_scale,
    )
