"""XYZ by plane touches (METHODS 7): the TCP from touches of flat surfaces whose place is unknown.

Model: touch i puts the tip on plane k(i): n_k . (R_i t + f_i) = d_k, with R_i (3, 3) flange ->
base, f_i (3,) the flange position in mm (base frame), t (3,) the TCP in the flange frame and
(n_k, d_k) the plane's unit normal and offset (base frame, mm). Unknowns: t and, per plane,
2 + 1: at least 3 + 3 K + 1 touches for K planes (one to spare, see MIN_POSES), at least 3
on each plane.

Estimate: nonlinear least squares on the signed distances r_i = n_k . (R_i t + f_i) - d_k
(scipy.optimize.least_squares, Levenberg-Marquardt), the normals moved on the sphere through
two tangent coordinates. Starts: the plane fitted to the tips under a start TCP (the active
TCP, else t = 0), and normals along the mean flange axes; for each start normal (t, d) is
solved linearly, then all six unknowns refined; the lowest cost wins.

Uncertainty: the touch error is isotropic with 1-sigma sigma_p per axis, so each signed
distance has sigma_p. Cov = sigma_p^2 (J^T J)^-1 at the solution (J the Jacobian of the
distances in t, the normals' tangent coordinates and the offsets), which is also the
Cramer-Rao bound of the model. Without a configured sigma_p it is estimated from the
residuals on N - 3 - 3K degrees of freedom; the covariance is then widened by
(t(0.975, nu) / 1.96)^2 so that +-1.96 sigma per axis stays a 95 % interval (Student's t, as
the laser method does), and the 95 % ellipsoid's scale is the F-based one divided by that
factor (so the ellipsoid is the Hotelling one, not widened twice).

Observability: t enters only through g_i = R_i^T n_k, the normal seen from the flange. If all
touches share one orientation (pure translations), or rotate only about one flange axis a
(all tool axes parallel when a is the tool axis; spins about the plane normal), the
component of t along a moves every touch's distance equally and cannot be told from d_k:
refused, naming the orientation to add. Tips at one spot or along one line of a plane leave
that plane's tilt free: refused, naming the plane.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.distributions import norm_ppf, t_ppf
from app.solvers.plane.checks import (
    AXIS_MATCH_DEG,
    DEGENERACY_RATIO,
    MIN_PER_PLANE,
    MIN_TIP_SPREAD_MM,
    PLANE_LABELS,
    RESIDUAL_FLOOR_MM,
    SHOWN_ALPHA,
    TRANSLATION_ONLY_DEG,
    canonical,
    check_bounded,
    check_orientations,
    check_tcp_shown,
    check_tip_spread,
    checked_touches,
    chi2_quantile,
    f_quantile,
    rotation_block,
    start_tcp,
)
from app.solvers.plane.model import PlaneTouches, distance_jacobian, signed_distances, unpack
from app.solvers.plane.search import (
    DISTINCT_START_DEG,
    GRID_DIRECTIONS,
    GRID_STARTS,
    SAME_MINIMUM_REL,
    fit_planes,
)
from app.solvers.quality import (
    ELLIPSOID_PROBABILITY,
    SIGMA_CONFIGURED,
    SIGMA_RESIDUALS,
    Quality,
    SigmaSource,
    format_vector,
    make_quality,
)

__all__ = [
    "AXIS_MATCH_DEG",
    "DEGENERACY_RATIO",
    "DISTINCT_START_DEG",
    "FEW_DOF",
    "GRID_DIRECTIONS",
    "GRID_STARTS",
    "MAX_CONDITION",
    "MIN_PER_PLANE",
    "MIN_POSES",
    "MIN_TIP_SPREAD_MM",
    "PLANE_LABELS",
    "RESIDUAL_FLOOR_MM",
    "SAME_MINIMUM_REL",
    "SHOWN_ALPHA",
    "TRANSLATION_ONLY_DEG",
    "WEAK_DIRECTION_RATIO",
    "FittedPlane",
    "PlaneResult",
    "check_predicted_sigma",
    "cramer_rao_tcp",
    "solve_plane",
    "widening",
]

#: Fewest touches of one plane: 3 unknowns for the TCP and 3 for the plane, and one more:
#: with exactly as many touches as unknowns the distances vanish at several solutions (about
#: half of 200 seeded exact 6-touch sets gave another exact one), nothing tells them apart.
MIN_POSES = 7
#: Warn when the rotation block's s_min / s_max (see DEGENERACY_RATIO) is below this (one
#: rotation axis dominates).
WEAK_DIRECTION_RATIO = 0.1
#: Refuse when the Jacobian's scaled condition number exceeds this (no unique solution).
MAX_CONDITION = 1e12
#: Below this many degrees of freedom an estimated touch noise is flagged as soft.
FEW_DOF = 6


@dataclass(frozen=True)
class FittedPlane:
    """One plane: label, unit normal (base frame), offset d (mm: n . x = d), their 1-sigma."""

    label: str
    normal: FloatArray
    offset_mm: float
    normal_sigma_deg: float
    offset_sigma_mm: float
    n_touches: int


@dataclass(frozen=True)
class PlaneResult:
    """TCP t (3,) mm in the flange frame, the planes, the quality, and the noise used."""

    tcp_mm: FloatArray
    planes: tuple[FittedPlane, ...]
    quality: Quality
    touch_noise_mm: float  # the noise behind the covariance (configured or estimated)
    dof: int  # residual degrees of freedom, N - 3 - 3K


def solve_plane(
    rotations: ArrayLike,
    positions_mm: ArrayLike,
    *,
    planes: Sequence[str] | None = None,
    touch_noise_mm: float | None = None,
    start_tcp_mm: ArrayLike | None = None,
    max_tcp_sigma_mm: float | None = None,
) -> PlaneResult:
    """Solve the TCP from N touches of up to three flat surfaces.

    rotations (N, 3, 3) flange -> base; positions_mm (N, 3). planes: each touch's plane label
    (None: one plane, "a"). touch_noise_mm: the 1-sigma touch error per axis; None: estimated
    from the residuals (needs more touches than unknowns). start_tcp_mm: a TCP to start from
    (the active one). max_tcp_sigma_mm: refuse ("insufficient-spread") when the TCP's
    1-sigma along its weakest direction exceeds it. Raises InvalidInput for touches that
    cannot give a trustworthy TCP.
    """
    touches = checked_touches(rotations, positions_mm, planes, touch_noise_mm)
    spread_deg = check_orientations(touches)
    x = fit_planes(touches, start_tcp(start_tcp_mm))
    t, normals, offsets = unpack(x, len(touches.labels))
    check_bounded(t, offsets)
    check_tip_spread(touches, t)
    residuals = signed_distances(touches, t, normals, offsets)
    jac = distance_jacobian(touches, t, normals)
    unit_cov = _unit_covariance(jac)
    n, p = jac.shape
    dof = n - p
    check_tcp_shown(touches, residuals, dof, touch_noise_mm)
    noise, source, widen = _noise(residuals, dof, touch_noise_mm)
    cov = (widen * noise) ** 2 * unit_cov
    cov_t = cov[:3, :3]
    if max_tcp_sigma_mm is not None:
        check_predicted_sigma(cov_t, max_tcp_sigma_mm, noise, source == SIGMA_CONFIGURED)
    warnings = _warnings(touches, residuals, dof, noise, touch_noise_mm)
    quality = make_quality(
        residuals_mm=np.abs(residuals),
        tcp_covariance_mm2=cov_t,
        sigma_source=source,
        orientation_spread_deg=spread_deg,
        condition_number=_condition(jac),
        warnings=tuple(warnings),
        dof=None if source == SIGMA_CONFIGURED else dof,
        ellipsoid_scale=_ellipsoid_scale(None if source == SIGMA_CONFIGURED else dof) / widen,
    )
    return PlaneResult(
        tcp_mm=np.array(t, dtype=np.float64),
        planes=_fitted_planes(touches, normals, offsets, cov),
        quality=quality,
        touch_noise_mm=noise,
        dof=dof,
    )


def cramer_rao_tcp(
    rotations: ArrayLike,
    positions_mm: ArrayLike,
    *,
    tcp_mm: ArrayLike,
    normals: ArrayLike,
    touch_noise_mm: float,
    planes: Sequence[str] | None = None,
) -> FloatArray:
    """The Cramer-Rao bound (3, 3) mm^2 of the TCP: sigma^2 (J^T J)^-1 of the signed
    distances at the true TCP and plane normals (K, 3), in the planes' sorted label order."""
    R = np.asarray(rotations, dtype=np.float64)
    given = ["a"] * R.shape[0] if planes is None else list(planes)
    labels = tuple(sorted(set(given)))
    touches = PlaneTouches(
        R=R,
        f=np.asarray(positions_mm, dtype=np.float64),
        plane=np.array([labels.index(lab) for lab in given], dtype=np.intp),
        labels=labels,
    )
    jac = distance_jacobian(
        touches, np.asarray(tcp_mm, dtype=np.float64), np.asarray(normals, dtype=np.float64)
    )
    bound = touch_noise_mm**2 * np.linalg.inv(jac.T @ jac)[:3, :3]
    return np.asarray(bound, dtype=np.float64)


def _column_scaled(jac: FloatArray) -> tuple[FloatArray, FloatArray]:
    scale = np.linalg.norm(jac, axis=0)
    scale[scale == 0.0] = 1.0
    return jac / scale, scale


def _condition(jac: FloatArray) -> float:
    scaled, _ = _column_scaled(jac)
    s = np.linalg.svd(scaled, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else math.inf


def _unit_covariance(jac: FloatArray) -> FloatArray:
    """(J^T J)^-1 through the column-scaled SVD; refuse a rank-deficient Jacobian."""
    scaled, scale = _column_scaled(jac)
    _, s, vt = np.linalg.svd(scaled, full_matrices=False)
    if s[-1] <= 0 or s[0] / s[-1] > MAX_CONDITION:
        raise InvalidInput(
            "degenerate-poses",
            "the touches do not determine the TCP and the planes together (the problem is "
            "singular); touch with the tool tilted in different directions, at points spread "
            "across each plane",
            loc=("poses",),
            context={"condition_number": float(s[0] / s[-1]) if s[-1] > 0 else None},
        )
    inv = (vt.T / s**2) @ vt
    cov: FloatArray = inv / np.outer(scale, scale)
    return 0.5 * (cov + cov.T)


def _noise(
    residuals: FloatArray, dof: int, touch_noise_mm: float | None
) -> tuple[float, SigmaSource, float]:
    """The touch noise behind the covariance, its source, and the Student's t widening."""
    if touch_noise_mm is not None:
        return float(touch_noise_mm), SIGMA_CONFIGURED, 1.0
    sigma = math.sqrt(float(np.sum(residuals**2)) / dof)
    return max(sigma, 0.0), SIGMA_RESIDUALS, widening(dof)


@lru_cache(maxsize=256)
def widening(dof: float) -> float:
    """t(0.975, dof) / 1.96: keeps +-1.96 sigma a 95 % interval when the noise behind sigma
    was estimated on dof degrees of freedom."""
    return float(t_ppf(0.975, dof) / norm_ppf(0.975))


def _ellipsoid_scale(dof: int | None) -> float:
    """k with (x - x^)^T Cov^-1 (x - x^) <= k^2 95 % of the time in 3-D: chi2 with a known
    noise, Hotelling's 3 F(3, dof) with one estimated on dof degrees of freedom."""
    if dof is None:
        return math.sqrt(chi2_quantile(ELLIPSOID_PROBABILITY, 3))
    return math.sqrt(3.0 * f_quantile(ELLIPSOID_PROBABILITY, 3, dof))


def check_predicted_sigma(
    cov_t: FloatArray, max_tcp_sigma_mm: float, noise: float, configured: bool
) -> None:
    """Refuse ("insufficient-spread") when the TCP's 1-sigma (cov_t, 3x3 mm^2) along its
    weakest direction exceeds max_tcp_sigma_mm; noise: the touch noise behind cov_t."""
    evals, evecs = np.linalg.eigh(0.5 * (cov_t + cov_t.T))
    worst = math.sqrt(max(float(evals[-1]), 0.0))
    if worst <= max_tcp_sigma_mm:
        return
    direction = canonical(evecs[:, -1])
    what = (
        f"the configured touch noise of {noise:g} mm"
        if configured
        else f"the touch noise estimated from the residuals ({noise:.3g} mm)"
    )
    raise InvalidInput(
        "insufficient-spread",
        f"with {what} the TCP is only determined to {worst:.3g} mm (1 sigma) along the flange "
        f"direction {format_vector(direction)}, more than the allowed {max_tcp_sigma_mm:g} mm: "
        "tilt the tool further from the plane's normal (the TCP along the tool axis is told "
        "from the plane's offset only by how much the tilts differ), in different directions",
        loc=("poses",),
        context={
            "predicted_sigma_mm": worst,
            "max_tcp_sigma_mm": float(max_tcp_sigma_mm),
            "direction_flange": [float(v) for v in direction],
        },
    )


def _fitted_planes(
    touches: PlaneTouches, normals: FloatArray, offsets: FloatArray, cov: FloatArray
) -> tuple[FittedPlane, ...]:
    out = []
    for j, label in enumerate(touches.labels):
        base = 3 + 3 * j
        tangent_var = float(cov[base, base] + cov[base + 1, base + 1])
        normal = normals[j]
        offset = float(offsets[j])
        if offset < 0:  # report the normal pointing away from the base origin's side
            normal, offset = -normal, -offset
        out.append(
            FittedPlane(
                label=label,
                normal=np.array(normal + 0.0, dtype=np.float64),
                offset_mm=offset,
                normal_sigma_deg=math.degrees(math.sqrt(max(tangent_var, 0.0) / 2.0)),
                offset_sigma_mm=math.sqrt(max(float(cov[base + 2, base + 2]), 0.0)),
                n_touches=int(np.sum(touches.plane == j)),
            )
        )
    return tuple(out)


def _warnings(
    touches: PlaneTouches,
    residuals: FloatArray,
    dof: int,
    noise: float,
    touch_noise_mm: float | None,
) -> list[str]:
    warnings = []
    ratio, axis = rotation_block(touches.R)
    if ratio < WEAK_DIRECTION_RATIO:
        warnings.append(
            f"the touches turn mostly about the flange axis {format_vector(axis)} (singular "
            f"value ratio {ratio:.3f}): the TCP along it is weakly determined; tilt the tool "
            "about another axis"
        )
    if touch_noise_mm is not None:
        chi2_stat = float(np.sum(residuals**2)) / touch_noise_mm**2
        if chi2_stat > chi2_quantile(1.0 - 1e-3, dof):
            rms = float(np.sqrt(np.mean(residuals**2)))
            worst = int(np.argmax(np.abs(residuals)))
            warnings.append(
                f"the distances to the plane (rms {rms:.3f} mm, largest {abs(residuals[worst]):.3f}"
                f" mm at touch #{worst + 1}) are larger than the configured touch noise of "
                f"{touch_noise_mm:g} mm explains: the reported uncertainty is probably optimistic"
            )
    elif dof < FEW_DOF:
        warnings.append(
            f"the touch noise was estimated from only {dof} degrees of freedom (the interval is "
            "widened for it); configure the tool's touch noise or add touches for a firmer one"
        )
    return warnings
