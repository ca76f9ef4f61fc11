"""fit_points: the rigid transform (no scale) that best maps a fixture's nominal points to the
touched ones, robust to one bad touch in five (METHODS.md 7).

Model: p_i = R n_i + o + e_i, with n_i the point's coordinates in the frame (a drawing, CAD)
and e_i the touch error, correlated across touches through the pointer's TCP
(`model.point_covariance`). The start is Kabsch's SVD solution of the cross-covariance with
the det = +1 correction (Umeyama 1991 without the scale); it is refined by Gauss-Newton on
the generalised least squares criterion r^T C^-1 r, the maximum-likelihood estimate under
the correlated noise model, whose covariance (A^T C^-1 A)^-1 is the Cramer-Rao bound.

Outliers: with N >= 5, each touch is predicted from a fit of the others; the touch whose
prediction error is least likely under the noise (chi-squared with 3 dof, or F with the
estimated noise level, Bonferroni over the touches at OUTLIER_ALPHA) is set aside while it
fails the test, at most one touch in five.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import permutations
from typing import Final

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.distributions import chi2_ppf, f_ppf
from app.solvers.frame.model import FrameEstimate, point_covariance, skew
from app.solvers.npoint.model import BoolArray
from app.solvers.numbering import numbered

MIN_POINTS: Final = 3
#: Points within this distance (mm) of one line leave the rotation about it unknown.
MIN_SPREAD_MM: Final = 1.0
#: Significance of the outlier test, over all touches together.
OUTLIER_ALPHA: Final = 0.01
#: At most one touch in this many is set aside.
TOUCHES_PER_OUTLIER: Final = 5
#: Gauss-Newton iterations of the generalised least squares refinement (quadratic
#: convergence from Kabsch's start: 3 reach machine precision on every test set).
GLS_ITERATIONS: Final = 4
#: The touches do not fit a rigid body when the rms misfit is this many noise sigmas...
MISFIT_SIGMAS: Final = 10.0
#: ...and above this (mm): a fixture drawing is not better than this.
MISFIT_FLOOR_MM: Final = 0.5
#: Units a drawing may be in, and what each is read as in mm.
UNIT_READINGS: Final = {"inch": 25.4, "cm": 10.0, "m": 1000.0}
#: Nominal points read in another axis order are tried up to this many touches in another order.
MAX_ORDER_TRIAL_POINTS: Final = 7


@dataclass(frozen=True)
class _Fit:
    R: FloatArray
    o: FloatArray
    cov: FloatArray


def kabsch(nominal: FloatArray, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(R, o) minimising sum |R n_i + o - p_i|^2 over rotations (det +1) and translations."""
    cn, cp = nominal.mean(axis=0), points.mean(axis=0)
    H = (nominal - cn).T @ (points - cp)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R: FloatArray = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    o: FloatArray = cp - R @ cn
    return R, o


def _design(R: FloatArray, nominal: FloatArray) -> FloatArray:
    """A (3N, 6): d r_i / d [delta o, delta theta] with R' = R exp([delta theta]x)."""
    n = nominal.shape[0]
    A = np.empty((n, 3, 6))
    A[:, :, :3] = np.eye(3)
    A[:, :, 3:] = -np.einsum("ij,njk->nik", R, skew(nominal))
    out: FloatArray = A.reshape(3 * n, 6)
    return out


def _gls(nominal: FloatArray, points: FloatArray, C: FloatArray) -> _Fit:
    R, o = kabsch(nominal, points)
    W = np.linalg.inv(C)
    for _ in range(GLS_ITERATIONS):
        r = (nominal @ R.T + o - points).ravel()
        A = _design(R, nominal)
        step = np.asarray(-np.linalg.solve(A.T @ W @ A, A.T @ W @ r), dtype=np.float64)
        o = o + step[:3]
        R = R @ _exp(step[3:])
    A = _design(R, nominal)
    cov = np.linalg.inv(A.T @ W @ A)
    return _Fit(R, o, 0.5 * (cov + cov.T))


def _exp(theta: FloatArray) -> FloatArray:
    out: FloatArray = Rotation.from_rotvec(theta).as_matrix()
    return out


def _index(used: BoolArray) -> FloatArray:
    out: FloatArray = np.array([3 * i + a for i in np.flatnonzero(used) for a in range(3)])
    return out


def check_spread(nominal: FloatArray) -> None:
    """Refuse nominal points that are fewer than 3, coincident, or on one line."""
    if nominal.shape[0] < MIN_POINTS:
        raise InvalidInput(
            "too-few-poses",
            f"fit_points needs at least {MIN_POINTS} touches with nominal_mm, not on one line; "
            f"got {nominal.shape[0]}",
            loc=("touches",),
        )
    centred = nominal - nominal.mean(axis=0)
    _, s, Vt = np.linalg.svd(centred, full_matrices=False)
    off_line = np.linalg.norm(centred - np.outer(centred @ Vt[0], Vt[0]), axis=1)
    if s[0] < MIN_SPREAD_MM or off_line.max() < MIN_SPREAD_MM:
        raise InvalidInput(
            "collinear-points",
            f"the nominal points lie within {off_line.max():.3f} mm of one line: the rotation "
            "about it is unknown; touch a point of the fixture away from that line",
            loc=("touches",),
        )


@dataclass(frozen=True)
class _Touches:
    """The touches of one fit: nominal (N, 3), points (N, 3), flange rotations (N, 3, 3)."""

    nominal: FloatArray
    points: FloatArray
    rotations: FloatArray
    tcp_covariance: FloatArray

    def covariance(self, used: BoolArray, sigma: float) -> FloatArray:
        return point_covariance(self.rotations[used], sigma, self.tcp_covariance)

    def fit(self, used: BoolArray, sigma: float) -> _Fit:
        return _gls(self.nominal[used], self.points[used], self.covariance(used, sigma))


def _estimated_sigma(t: _Touches, used: BoolArray) -> float:
    """The touch noise from the residuals of the used touches' rigid fit (3 n - 6 dof)."""
    R, o = kabsch(t.nominal[used], t.points[used])
    r = (t.nominal[used] @ R.T + o - t.points[used]).ravel()
    dof = max(r.size - 6, 1)
    return max(math.sqrt(float(r @ r) / dof), 1e-9)


def _worst_prediction(
    t: _Touches, used: BoolArray, configured: float | None
) -> tuple[int, float, float]:
    """(i, statistic, threshold) for the used touch least like the others' prediction."""
    candidates = np.flatnonzero(used)
    n_used = candidates.size
    worst = (-1, -math.inf, 0.0)
    for i in candidates:
        rest = used.copy()
        rest[i] = False
        sigma = configured if configured is not None else _estimated_sigma(t, rest)
        fit = t.fit(rest, sigma)
        e = fit.R @ t.nominal[i] + fit.o - t.points[i]
        J = np.hstack([np.eye(3), -fit.R @ skew(t.nominal[i])])
        V = sigma**2 * np.eye(3) + J @ fit.cov @ J.T
        if configured is None:
            threshold = 3.0 * f_ppf(1.0 - OUTLIER_ALPHA / n_used, 3, 3 * (n_used - 1) - 6)
        else:
            threshold = chi2_ppf(1.0 - OUTLIER_ALPHA / n_used, 3)
        statistic = float(e @ np.linalg.solve(V, e))
        if statistic / threshold > worst[1] / max(worst[2], 1e-300):
            worst = (int(i), statistic, threshold)
    return worst


def set_aside(t: _Touches, configured: float | None) -> BoolArray:
    """The touches to use (N,) bool: all but those the prediction test sets aside, at most
    one in TOUCHES_PER_OUTLIER."""
    n = t.nominal.shape[0]
    used: BoolArray = np.ones(n, dtype=bool)
    for _ in range(n // TOUCHES_PER_OUTLIER):
        i, statistic, threshold = _worst_prediction(t, used, configured)
        if i < 0 or statistic <= threshold:
            break
        used[i] = False
    return used


def fit_points(
    nominal_mm: ArrayLike,
    points_mm: ArrayLike,
    rotations: ArrayLike,
    tcp_covariance_mm2: ArrayLike,
    *,
    touch_noise_mm: float | None,
) -> FrameEstimate:
    """The frame mapping nominal points (N, 3) mm (frame coordinates) to touched points
    (N, 3) mm (base frame), touched with flange rotations (N, 3, 3) by a pointer whose TCP
    has the covariance (3, 3) mm^2. touch_noise_mm None: estimated from the residuals."""
    t = _Touches(
        np.asarray(nominal_mm, dtype=np.float64),
        np.asarray(points_mm, dtype=np.float64),
        np.asarray(rotations, dtype=np.float64),
        np.asarray(tcp_covariance_mm2, dtype=np.float64),
    )
    check_spread(t.nominal)
    if touch_noise_mm is None and t.nominal.shape[0] * 3 - 6 <= 0:
        raise InvalidInput(
            "invalid-options",
            "three touches leave no residual to estimate the touch noise from: give "
            "options.touch_noise_mm, set the frame's tolerance.touch_noise_mm, or add a fourth "
            "touch",
            loc=("options", "touch_noise_mm"),
        )
    limit = misfit_limit(touch_noise_mm)
    if _rigid_rms(t.nominal, t.points) > limit:  # a unit or order mix-up misfits every touch
        suggest_reading(t.nominal, t.points, limit)
    used = set_aside(t, touch_noise_mm)
    sigma = touch_noise_mm if touch_noise_mm is not None else _estimated_sigma(t, used)
    fit = t.fit(used, sigma)
    residuals = np.linalg.norm(t.nominal @ fit.R.T + fit.o - t.points, axis=1)
    check_rigid(t.nominal[used], t.points[used], residuals[used], limit, np.flatnonzero(used))
    warnings = []
    if not used.all():
        warnings.append(
            f"{numbered('touch', np.flatnonzero(~used))} set aside: "
            "far from where the other touches put it"
        )
    return FrameEstimate(
        rotation=fit.R,
        origin_mm=fit.o,
        covariance=fit.cov,
        points_mm=t.points,
        nominal_mm=t.nominal,
        residuals_mm=residuals,
        used=used,
        touch_noise_mm=sigma,
        sigma_source="configured" if touch_noise_mm is not None else "residuals",
        dof=None if touch_noise_mm is not None else 3 * int(used.sum()) - 6,
        warnings=tuple(warnings),
    )


def rms(values: FloatArray) -> float:
    """Root mean square of the values."""
    return float(np.sqrt(np.mean(np.square(values)))) if values.size else 0.0


def misfit_limit(touch_noise_mm: float | None) -> float:
    """The rms (mm) past which touches do not fit a rigid body: MISFIT_SIGMAS configured
    sigmas, never below MISFIT_FLOOR_MM (an estimated noise level grows with the misfit, so
    then the floor alone)."""
    if touch_noise_mm is None:
        return MISFIT_FLOOR_MM
    return max(MISFIT_SIGMAS * touch_noise_mm, MISFIT_FLOOR_MM)


def suggest_reading(nominal: FloatArray, points: FloatArray, limit: float) -> None:
    """Raise `convention-mismatch` when another reading of the nominal points fits."""
    suggestion = other_reading(nominal, points, limit)
    if suggestion is None:
        return
    words, fitted = suggestion
    given = _rigid_rms(nominal, points)
    raise InvalidInput(
        "convention-mismatch",
        f"the nominal points do not fit the touches as given (rms {given:.3f} mm) but fit "
        f"{words} (rms {fitted:.3f} mm): resend them so",
        loc=("touches",),
        members={"suggestion": {"nominal_mm": words, "rms_mm": fitted}},
    )


def check_rigid(
    nominal: FloatArray,
    points: FloatArray,
    residuals: FloatArray,
    limit: float,
    touch_index: ArrayLike,
) -> None:
    """Refuse nominal points the touches do not fit as a rigid body, suggesting the reading
    (units, axis order, touch order) under which they do, else naming the worst touch."""
    if rms(residuals) <= limit:
        return
    suggest_reading(nominal, points, limit)
    at = int(np.argmax(residuals))
    worst = int(np.asarray(touch_index)[at])
    raise InvalidInput(
        "rigid-misfit",
        f"the nominal points do not fit the touches as a rigid body: rms {rms(residuals):.3f} "
        f"mm, touch {worst + 1} off by {residuals[at]:.3f} mm; check each touch's "
        "nominal_mm against the drawing (same point, same order, mm)",
        loc=("touches", worst, "nominal_mm"),
        context={"rms_mm": rms(residuals)},
    )


def _rigid_rms(nominal: FloatArray, points: FloatArray) -> float:
    R, o = kabsch(nominal, points)
    return rms(np.linalg.norm(nominal @ R.T + o - points, axis=1))


def other_reading(
    nominal: FloatArray, points: FloatArray, limit: float
) -> tuple[str, float] | None:
    """The one simplest other reading of the nominal points that fits within `limit` mm rms:
    another unit, a left-handed reading of the axes (two swapped, or one negated), or the
    touches in another order (only up to MAX_ORDER_TRIAL_POINTS touches)."""
    for unit, scale in UNIT_READINGS.items():
        fitted = _rigid_rms(nominal * scale, points)
        if fitted <= limit:
            return f"read in {unit} (x {scale:g} to mm)", fitted
    mirrored = nominal * np.array([1.0, 1.0, -1.0])
    fitted = _rigid_rms(mirrored, points)
    if fitted <= limit:
        # Every left-handed reading fits alike (any two differ by a rotation), and each gives
        # another frame: the drawing, not the touches, tells which one is meant.
        return (
            "mirrored: two of the drawing's axes swapped (y x z, z y x or x z y) or one of them "
            "negated; read the axes as the drawing defines them",
            fitted,
        )
    if nominal.shape[0] <= MAX_ORDER_TRIAL_POINTS:
        for touches in permutations(range(nominal.shape[0])):
            fitted = _rigid_rms(nominal[list(touches)], points)
            if fitted <= limit:
                listed = ", ".join(str(t + 1) for t in touches)
                return f"as the nominal points of touches {listed}, in that order", fitted
    return None
