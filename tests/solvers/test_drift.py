"""Drift trend: coverage of the rate interval, false alarms of the projection, robustness."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import binom

from app.errors import InvalidInput
from app.solvers.drift import MONTH_DAYS, Trend, crossing, fit_trend

FloatArray = np.ndarray
N_SERIES = 1000
#: Steady series simulated for the false `drifting` rate (about 2 ms of CPU each).
FALSE_SERIES = 2000
DOCS = Path(__file__).resolve().parents[2] / "docs" / "drift.md"
#: "drifting": the projection crosses check_mm within this many days of the last point.
WITHIN_DAYS = 30.0


def _times(rng: np.random.Generator, n: int, span_days: float) -> FloatArray:
    """n irregular times over span_days (first at 0, last at the span)."""
    inner = np.sort(rng.uniform(0.0, span_days, n - 2))
    return np.concatenate([[0.0], inner, [span_days]])


def _series(
    rng: np.random.Generator, n: int, span: float, level: FloatArray, rate: FloatArray, noise: float
) -> tuple[FloatArray, FloatArray]:
    t = _times(rng, n, span)
    y = level + np.outer(t / MONTH_DAYS, rate) + rng.normal(0.0, noise, (n, 3))
    return t, y


def _fit(t: FloatArray, y: FloatArray) -> Trend:
    trend = fit_trend(t, y)
    assert trend is not None
    return trend


def _drifting(trend: Trend, reference: FloatArray, limit: float) -> bool:
    at = crossing(trend, reference_mm=reference, limit_mm=limit)
    return at is not None and at <= trend.last_days + WITHIN_DAYS


def test_rate_interval_covers_the_true_rate_95_percent_of_the_time() -> None:
    rng = np.random.default_rng(20261124)
    hits = 0
    for _ in range(N_SERIES):
        n = int(rng.integers(3, 31))
        rate = rng.normal(0.0, 0.05, 3)
        t, y = _series(
            rng, n, rng.uniform(20.0, 400.0), rng.normal(0, 100, 3), rate, rng.uniform(0.01, 0.2)
        )
        trend = _fit(t, y)
        axis = int(rng.integers(3))
        hits += bool(trend.low_mm_per_month[axis] <= rate[axis] <= trend.high_mm_per_month[axis])
    assert 0.93 <= hits / N_SERIES <= 0.97, hits


def _documented_false_drifting() -> float:
    """The share of steady series at check_mm that raise `drifting`, as docs/drift.md states
    it (the figure measured over 40 000 series)."""
    text = DOCS.read_text()
    match = re.search(r"stand exactly at `check_mm` \(the hardest case\), ([0-9.]+) %", text)
    assert match is not None, "docs/drift.md no longer states the false `drifting` rate"
    return float(match.group(1)) / 100.0


def test_no_drift_raises_drifting_at_the_documented_rate() -> None:
    """Deviations that do not move, standing right at check_mm (the hardest case: 0.9 mm gives
    no alarm at all): a false alarm is a lower bound above the truth somewhere in the 30
    days. The count over FALSE_SERIES series must lie in the central 99.8 % of the binomial
    distribution at the documented rate (5.3 %, above the bound's nominal 5 %: the 30 days
    are 30 chances), [76, 138] of 2000: a detector at 7.5 % fails for 86 % of seeds, and one
    at the documented rate passes for 998 seeds of 1000."""
    rate = _documented_false_drifting()
    low, high = binom.ppf([0.001, 0.999], FALSE_SERIES, rate)
    rng = np.random.default_rng(7)
    raised = 0
    for _ in range(FALSE_SERIES):
        n = int(rng.integers(4, 25))
        direction = rng.normal(size=3)
        level = 1.0 * direction / np.linalg.norm(direction)
        t, y = _series(rng, n, rng.uniform(30.0, 300.0), level, np.zeros(3), 0.05)
        raised += _drifting(_fit(t, y), np.zeros(3), 1.0)
    assert low <= raised <= high, (raised, FALSE_SERIES, (low, high))


def test_a_real_drift_towards_check_mm_is_raised_with_a_crossing_time() -> None:
    """0.08 mm/month along Z from 0 for a year (with 0.02 mm noise): 0.96 mm now, 1.0 mm in
    about two weeks."""
    rng = np.random.default_rng(3)
    t, y = _series(rng, 13, 365.0, np.zeros(3), np.array([0.0, 0.0, 0.08]), 0.02)
    trend = _fit(t, y)
    at = crossing(trend, reference_mm=np.zeros(3), limit_mm=1.0)
    assert at is not None
    assert trend.last_days <= at <= trend.last_days + WITHIN_DAYS
    assert _drifting(trend, np.zeros(3), 1.0)
    assert_allclose(trend.rate_mm_per_month, [0.0, 0.0, 0.08], atol=0.01)


def test_a_slow_drift_is_measured_but_not_raised() -> None:
    rng = np.random.default_rng(4)
    t, y = _series(rng, 13, 365.0, np.zeros(3), np.array([0.0, 0.0, 0.01]), 0.02)
    trend = _fit(t, y)
    assert trend.low_mm_per_month[2] > 0.0  # the drift is seen...
    assert not _drifting(trend, np.zeros(3), 1.0)  # ...but far from check_mm


def test_one_wild_point_does_not_swing_the_rate() -> None:
    rng = np.random.default_rng(11)
    t, y = _series(rng, 15, 300.0, np.array([0, 0, 400.0]), np.array([0, 0, -0.05]), 0.03)
    clean = _fit(t, y)
    y_wild = y.copy()
    y_wild[12, 2] += 8.0  # a crash or a missed touch, 8 mm off
    wild = _fit(t, y_wild)
    assert abs(wild.rate_mm_per_month[2] - clean.rate_mm_per_month[2]) < 0.01
    assert abs(wild.rate_mm_per_month[2] - -0.05) < 3 * wild.sigma_mm_per_month[2]
    assert 12 in wild.outliers
    # least squares would have moved by more than ten times as much
    slope_ls = np.polyfit(t / MONTH_DAYS, y_wild[:, 2], 1)[0]
    assert abs(slope_ls - clean.rate_mm_per_month[2]) > 0.01


def test_noise_free_series_are_exact() -> None:
    t = np.array([0.0, 17.0, 40.5, 90.0, 200.0, 390.0])
    rate = np.array([0.01, -0.02, -0.0485])
    y = np.array([1.0, -2.0, 402.494]) + np.outer(t / MONTH_DAYS, rate)
    trend = _fit(t, y)
    assert_allclose(trend.rate_mm_per_month, rate, atol=1e-12)
    assert_allclose(trend.sigma_mm_per_month, 0.0, atol=1e-12)
    assert_allclose(trend.at(390.0)[0], y[-1], atol=1e-9)
    # |v(t) - v(390)| = |rate| (t - 390) / MONTH_DAYS reaches 0.5 mm at a known time
    at = crossing(trend, reference_mm=y[-1], limit_mm=0.5)
    assert at is not None
    assert_allclose(at, 390.0 + 0.5 / np.linalg.norm(rate) * MONTH_DAYS, atol=1e-4)


def test_the_torch_from_the_issue() -> None:
    """Z 402.494 -> 401.864 mm over 13 months of versions: about -0.048 mm/month."""
    months = np.arange(14.0)
    z = np.linspace(402.494, 401.864, 14) + np.random.default_rng(1).normal(0, 0.01, 14)
    y = np.column_stack([np.zeros(14), np.zeros(14), z])
    trend = _fit(months * MONTH_DAYS, y)
    assert trend.low_mm_per_month[2] < -0.63 / 13 < trend.high_mm_per_month[2]
    assert trend.high_mm_per_month[2] < 0.0


@pytest.mark.parametrize(
    ("t", "n"),
    [([0.0, 10.0], 2), ([0.0, 0.2, 0.5, 0.9], 4), ([5.0, 5.0, 5.0], 3)],
    ids=["two-points", "under-a-day", "one-moment"],
)
def test_too_little_gives_no_trend(t: list[float], n: int) -> None:
    assert fit_trend(t, np.zeros((n, 3))) is None


def test_a_flat_series_never_crosses() -> None:
    trend = _fit(np.array([0.0, 30.0, 60.0]), np.full((3, 3), 0.2))
    assert crossing(trend, reference_mm=np.zeros(3), limit_mm=1.0) is None


@pytest.mark.parametrize(
    ("t", "y"),
    [
        ([0.0, 1.0, np.nan], np.zeros((3, 3))),
        ([0.0, 1.0, 2.0], np.zeros((3, 2))),
        ([0.0, 1.0, 2.0], [[0, 0, 0], [0, np.inf, 0], [0, 0, 0]]),
    ],
    ids=["nan-time", "two-axes", "inf-value"],
)
def test_malformed_series_are_refused(t: list[float], y: object) -> None:
    with pytest.raises(InvalidInput):
        fit_trend(t, y)  # type: ignore[arg-type]
