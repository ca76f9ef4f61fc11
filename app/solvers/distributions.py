"""The few quantiles and normal-distribution values the solvers need, from scipy.special.

scipy.stats costs about half a second of CPU to import (it pulls in scipy.optimize,
scipy.integrate, scipy.interpolate, ...), and every tcpcal process imports the solvers: each
server worker, each solver process, `tcpcal publish`. These functions are what scipy.stats'
chi2, f, t and norm compute internally (scipy/stats/_continuous_distns.py: their `_ppf`,
`_cdf`, `_sf`, `_pdf`, which `ppf`, `cdf`, ... call for a valid argument with loc 0 and
scale 1), so the results are the same floats, bit for bit
(tests/solvers/test_distributions.py compares them on a grid). As scipy.stats does, a degree of
freedom that is not > 0 gives nan (scipy.special alone would give 0.0 for chi2 with 0 dof and q
near 1). q is a probability strictly between 0 and 1.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

#: As scipy.stats computes it (numpy's exp and sqrt, which may differ from math's in the last bit).
_NORM_PDF_C = np.sqrt(2 * np.pi)


def chi2_ppf(q: float, dof: float) -> float:
    """Quantile of chi-squared with `dof` degrees of freedom (scipy.stats.chi2.ppf)."""
    if not dof > 0:
        return math.nan
    return float(2.0 * special.gammaincinv(dof / 2, q))


def f_ppf(q: float, dfn: float, dfd: float) -> float:
    """Quantile of Fisher's F(dfn, dfd) (scipy.stats.f.ppf)."""
    if not (dfn > 0 and dfd > 0):
        return math.nan
    return float(special.fdtri(dfn, dfd, q))


def t_ppf(q: float, dof: float) -> float:
    """Quantile of Student's t with `dof` degrees of freedom (scipy.stats.t.ppf)."""
    if not dof > 0:
        return math.nan
    return float(special.stdtrit(dof, q))


def norm_ppf(q: float) -> float:
    """Quantile of the standard normal (scipy.stats.norm.ppf)."""
    return float(special.ndtri(q))


def norm_cdf(x: float) -> float:
    """Standard normal distribution function (scipy.stats.norm.cdf)."""
    return float(special.ndtr(x))


def norm_sf(x: float) -> float:
    """Standard normal survival function, 1 - cdf (scipy.stats.norm.sf)."""
    return float(special.ndtr(-x))


def norm_pdf(x: float) -> float:
    """Standard normal density (scipy.stats.norm.pdf)."""
    return float(np.exp(-(x**2) / 2.0) / _NORM_PDF_C)
