"""app.solvers.distributions gives the same floats as scipy.stats, bit for bit, on a grid of
the probabilities and degrees of freedom the solvers use and around them."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import stats

from app.solvers import distributions as d

PROBABILITIES = (
    1e-12, 1e-6, 1e-3, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 0.68, 0.75, 0.9, 0.95, 0.975, 0.99,
    1.0 - 1e-3, 1.0 - 1e-6, 1.0 - 1e-12,
)  # fmt: skip
#: Integer and fractional (effective) degrees of freedom, small to large, and invalid ones
#: (nan from both).
DOFS = (
    -1, 0, np.nan, 0.5, 1, 1.5, 2, 3, 3.7, 4, 5, 6, 7.25, 9, 12, 15, 20, 30, 45.5, 60, 100, 333,
    1000, 1e5, np.inf,
)  # fmt: skip
XS = (*np.linspace(-8.0, 8.0, 161).tolist(), 1.345, -1.345, 1.959963984540054, 37.5, -37.5)


def same(a: float, b: float) -> bool:
    return a == b or (np.isnan(a) and np.isnan(b))


@pytest.mark.parametrize("dof", DOFS)
def test_chi2_ppf(dof: float) -> None:
    for q in PROBABILITIES:
        assert same(d.chi2_ppf(q, dof), float(stats.chi2.ppf(q, dof))), (q, dof)


@pytest.mark.parametrize("dfn", [-1, 0, 1, 2, 3, 4.5])
def test_f_ppf(dfn: float) -> None:
    for q, dfd in itertools.product(PROBABILITIES, DOFS):
        assert same(d.f_ppf(q, dfn, dfd), float(stats.f.ppf(q, dfn, dfd))), (q, dfn, dfd)


@pytest.mark.parametrize("dof", DOFS)
def test_t_ppf(dof: float) -> None:
    for q in PROBABILITIES:
        assert same(d.t_ppf(q, dof), float(stats.t.ppf(q, dof))), (q, dof)


def test_norm() -> None:
    for q in PROBABILITIES:
        assert same(d.norm_ppf(q), float(stats.norm.ppf(q))), q
    frozen = stats.norm()  # as app.solvers.drift used it
    for x in XS:
        assert same(d.norm_cdf(x), float(frozen.cdf(x))), x
        assert same(d.norm_sf(x), float(frozen.sf(x))), x
        assert same(d.norm_pdf(x), float(frozen.pdf(x))), x
