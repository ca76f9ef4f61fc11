"""Drift trend: a robust straight line through a 3-D series over time, and when it projects
past a limit.

The series is a tool's TCP position over its versions, or its check deviations over time
(each check's deviation from the active TCP). Each axis gets its own line
y = level + rate (t - t0), t0 the mean time, rates in mm per month (30.44 days).

The fit is a Huber M-estimator (k = 1.345) by iteratively reweighted least squares, started
from the Theil-Sen line (the median of the pairwise slopes), with Huber's "proposal 2" scale
estimated jointly; the covariance is Huber's H1 sandwich with his small-sample correction, and
the 95 % interval uses Student's t with n - 2 degrees of freedom. Why this and not Theil-Sen's own
interval: Sen's interval comes from the ranks of the n(n-1)/2 pairwise slopes, so it cannot
reach 95 % below five points (with three points it covers the true rate 67 % of the time, with
four 92 %) and is too wide from five to ten (98-99 %); on 1000 simulated series per size
(Gaussian noise, irregular times) the Huber-t interval covered the true rate 94-96 % of the time
from three points to forty (tests/solvers/test_drift.py holds the coverage to 93-97 %). Robust
here means bounded influence: a point beyond 1.345 scale units counts with weight
1.345 s / |r|, so one wild point (a crash, a missed touch) moves the rate by at most a few
noise-sized steps instead of dragging it. It does not mean a step is understood: a tool bent
in a crash and calibrated again is a step, which a line reads as a rate.

`crossing` projects the line forward: the deviation from a reference position (the active
TCP) at time t is |v(t) - ref|, and its one-sided 95 % lower bound subtracts t_{0.95, n-2}
standard errors along the deviation's direction. The first time that lower bound reaches the
limit is when the tool is projected out of `check_mm` at 95 % confidence.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.distributions import norm_cdf, norm_pdf, norm_sf, t_ppf

#: Days per month in every rate (365.25 / 12).
MONTH_DAYS = 30.44
#: Fewer points than this, or a span shorter than MIN_SPAN_DAYS, gives no trend.
MIN_POINTS = 3
MIN_SPAN_DAYS = 1.0
#: Huber's tuning constant: 95 % efficiency on Gaussian noise.
HUBER_K = 1.345
#: Two-sided level of the rate interval; one-sided level of the projection's lower bound.
LEVEL = 0.95
#: How far ahead `crossing` looks by default (days).
HORIZON_DAYS = 730.0
#: A residual beyond this many scale units is reported as an outlier (it still counts, with
#: Huber's small weight).
OUTLIER_UNITS = 3.0

#: E[psi(Z)^2] for Z ~ N(0, 1): makes proposal 2's scale the standard deviation on Gaussian noise.
_PSI2 = float(
    (2 * norm_cdf(HUBER_K) - 1)
    - 2 * HUBER_K * norm_pdf(HUBER_K)
    + 2 * HUBER_K**2 * norm_sf(HUBER_K)
)


@dataclass(frozen=True, slots=True)
class Line:
    """One axis: y = level + rate (t - t0), with the standard errors (uncorrelated: the time
    is centred) and the noise scale the fit found."""

    level: float
    rate: float
    level_sigma: float
    rate_sigma: float
    scale: float
    outliers: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class Trend:
    """A 3-D series' straight line: per axis rate (mm/month) with its standard error and 95 %
    interval; level (mm) at t0 (days, the mean time of the points)."""

    t0_days: float
    first_days: float
    last_days: float
    n: int
    level_mm: FloatArray
    level_sigma_mm: FloatArray
    rate_mm_per_month: FloatArray
    sigma_mm_per_month: FloatArray
    low_mm_per_month: FloatArray
    high_mm_per_month: FloatArray
    outliers: tuple[int, ...]

    @property
    def dof(self) -> int:
        return self.n - 2

    @property
    def speed_mm_per_month(self) -> float:
        """Length of the rate vector: how fast the point moves, whatever the direction."""
        return float(np.linalg.norm(self.rate_mm_per_month))

    @property
    def speed_sigma_mm_per_month(self) -> float:
        """Standard error of the speed along the rate's direction (delta method); the largest
        axis error when the rate is exactly zero."""
        speed = self.speed_mm_per_month
        if speed == 0.0:
            return float(self.sigma_mm_per_month.max())
        u = self.rate_mm_per_month / speed
        return float(np.sqrt(np.sum((u * self.sigma_mm_per_month) ** 2)))

    def at(self, t_days: float) -> tuple[FloatArray, FloatArray]:
        """The line's value (mm) at t and its per-axis standard error."""
        tau = (t_days - self.t0_days) / MONTH_DAYS
        value = self.level_mm + self.rate_mm_per_month * tau
        sigma = np.sqrt(self.level_sigma_mm**2 + (tau * self.sigma_mm_per_month) ** 2)
        return value, sigma

    def lower_distance(self, t_days: ArrayLike, reference_mm: ArrayLike) -> FloatArray:
        """One-sided 95 % lower bound of |v(t) - reference| (mm) at each time, never below
        zero: the distance less t_{0.95, n-2} standard errors along the deviation."""
        tau = (np.atleast_1d(np.asarray(t_days, dtype=np.float64)) - self.t0_days) / MONTH_DAYS
        d = self.level_mm + np.outer(tau, self.rate_mm_per_month) - np.asarray(reference_mm)
        var = self.level_sigma_mm**2 + np.outer(tau**2, self.sigma_mm_per_month**2)
        dist = np.linalg.norm(d, axis=1)
        safe = np.where(dist > 0.0, dist, 1.0)
        along = np.sqrt(np.sum((d / safe[:, None]) ** 2 * var, axis=1))
        q = _t(LEVEL, self.dof)
        out: FloatArray = np.maximum(0.0, dist - q * along)
        return out


def fit_trend(times_days: ArrayLike, values_mm: ArrayLike) -> Trend | None:
    """The robust line through a (n, 3) series at times in days; None with fewer than three
    points or a span under a day (no trend can be told from them)."""
    t = np.asarray(times_days, dtype=np.float64)
    y = np.asarray(values_mm, dtype=np.float64)
    if t.ndim != 1 or y.shape != (t.size, 3):
        raise InvalidInput(
            "validation",
            f"a drift series is n times and n x 3 values, got {t.shape} and {y.shape}",
            loc=("values_mm",),
        )
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise InvalidInput("non-finite", "a drift series must be finite", loc=("values_mm",))
    if t.size < MIN_POINTS or float(np.ptp(t)) < MIN_SPAN_DAYS:
        return None
    t0 = float(t.mean())
    tau = (t - t0) / MONTH_DAYS
    lines = _huber_lines(tau, y)
    q = _t(0.5 + LEVEL / 2, t.size - 2)
    rate = np.array([ln.rate for ln in lines])
    sigma = np.array([ln.rate_sigma for ln in lines])
    return Trend(
        t0_days=t0,
        first_days=float(t.min()),
        last_days=float(t.max()),
        n=int(t.size),
        level_mm=np.array([ln.level for ln in lines]),
        level_sigma_mm=np.array([ln.level_sigma for ln in lines]),
        rate_mm_per_month=rate,
        sigma_mm_per_month=sigma,
        low_mm_per_month=rate - q * sigma,
        high_mm_per_month=rate + q * sigma,
        outliers=tuple(sorted({i for ln in lines for i in ln.outliers})),
    )


def _huber_lines(tau: FloatArray, y: FloatArray, max_iter: int = 200) -> list[Line]:
    """Huber IRLS of each column of y (n, 3) on centred time tau (months), proposal-2 scale,
    H1 covariance; the three axes iterate together (closed-form weighted least squares)."""
    n = tau.size
    beta = _theil_sen(tau, y)  # (2, 3): level, rate
    r = y - beta[0] - np.outer(tau, beta[1])
    scale = 1.4826 * np.median(np.abs(r - np.median(r, axis=0)), axis=0)
    rms = np.sqrt(np.sum(r**2, axis=0) / (n - 2))
    scale = np.where(scale > 0.0, scale, rms)
    live = scale > 0.0  # an axis with every point on the line is exact as it is
    for _ in range(max_iter):
        if not live.any():
            break
        safe = np.where(live, scale, 1.0)
        u = (y - beta[0] - np.outer(tau, beta[1])) / safe
        psi = np.clip(u, -HUBER_K, HUBER_K)
        new_scale = safe * np.sqrt(np.sum(psi**2, axis=0) / ((n - 2) * _PSI2))
        w = np.where(np.abs(u) <= HUBER_K, 1.0, HUBER_K / np.maximum(np.abs(u), 1e-300))
        new_beta = _weighted_line(tau, y, w)
        step = np.max(np.abs(new_beta - beta), axis=0)
        moved = np.abs(new_scale - safe)
        beta = np.where(live, new_beta, beta)
        scale = np.where(live, new_scale, scale)
        done = (step <= 1e-9 * (1.0 + np.max(np.abs(beta), axis=0))) & (moved <= 1e-7 * scale)
        live &= ~done & (scale > 0.0)
    return [_line_with_errors(tau, y[:, i], beta[:, i], float(scale[i])) for i in range(3)]


def _theil_sen(tau: FloatArray, y: FloatArray) -> FloatArray:
    """The Theil-Sen line of each column: the median of the pairwise slopes (pairs at one
    time left out), and the median intercept; (2, 3)."""
    i, j = np.triu_indices(tau.size, 1)
    dt = tau[j] - tau[i]
    keep = dt != 0.0
    slope = np.median((y[j][keep] - y[i][keep]) / dt[keep][:, None], axis=0)
    level = np.median(y - np.outer(tau, slope), axis=0)
    return np.vstack([level, slope])


def _weighted_line(tau: FloatArray, y: FloatArray, w: FloatArray) -> FloatArray:
    """Weighted least squares of each column of y on (1, tau) with its weights; (2, 3)."""
    sw = w.sum(axis=0)
    mt = (w * tau[:, None]).sum(axis=0) / sw
    my = (w * y).sum(axis=0) / sw
    dt = tau[:, None] - mt
    slope = (w * dt * (y - my)).sum(axis=0) / (w * dt**2).sum(axis=0)
    return np.vstack([my - slope * mt, slope])


def _line_with_errors(tau: FloatArray, y: FloatArray, beta: FloatArray, scale: float) -> Line:
    n = tau.size
    if scale == 0.0:
        return Line(float(beta[0]), float(beta[1]), 0.0, 0.0, 0.0, ())
    u = (y - beta[0] - beta[1] * tau) / scale
    psi = np.clip(u, -HUBER_K, HUBER_K)
    inside = float(np.mean(np.abs(u) <= HUBER_K))
    outliers = tuple(int(i) for i in np.flatnonzero(np.abs(u) > OUTLIER_UNITS))
    if inside == 0.0:
        return Line(float(beta[0]), float(beta[1]), np.inf, np.inf, scale, outliers)
    k = 1.0 + 2.0 / n * (1.0 - inside) / inside
    var = k**2 * (float(np.sum(psi**2)) / (n - 2)) / inside**2 * scale**2
    # (X^T X)^-1 of X = [1, tau] with tau centred: diagonal
    return Line(
        level=float(beta[0]),
        rate=float(beta[1]),
        level_sigma=float(np.sqrt(var / n)),
        rate_sigma=float(np.sqrt(var / float(np.sum(tau**2)))),
        scale=scale,
        outliers=outliers,
    )


@lru_cache(maxsize=256)
def _t(level: float, dof: int) -> float:
    """Student's t quantile (scipy's ppf costs ~0.1 ms a call)."""
    return t_ppf(level, dof)


def crossing(
    trend: Trend,
    *,
    reference_mm: ArrayLike,
    limit_mm: float,
    start_days: float | None = None,
    horizon_days: float = HORIZON_DAYS,
) -> float | None:
    """The first time (days) from `start_days` (default the last point) within the horizon at
    which the 95 % lower bound of |v(t) - reference| reaches `limit_mm`; `start_days` itself
    when it already has; None when it does not within the horizon."""
    ref = np.asarray(reference_mm, dtype=np.float64)
    start = trend.last_days if start_days is None else start_days

    def excess(t: float) -> float:
        return float(trend.lower_distance(t, ref)[0]) - limit_mm

    if excess(start) >= 0.0:
        return start
    grid = start + np.arange(1.0, horizon_days + 1.0)
    hit = np.flatnonzero(trend.lower_distance(grid, ref) >= limit_mm)
    if hit.size == 0:
        return None
    hi = float(grid[hit[0]])
    from scipy.optimize import brentq  # a few hundred ms to import: by the first crossing only

    return float(brentq(excess, hi - 1.0, hi, xtol=1e-6))
