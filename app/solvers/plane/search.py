"""The xyz_plane fit: start normals (fitted planes, mean flange axes, a profiled hemisphere grid),
Levenberg-Marquardt from each, the least-cost minimum polished by Gauss-Newton.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.plane.model import (
    PlaneTouches,
    distance_jacobian,
    signed_distances,
    tangents,
    unpack,
)

#: Directions of the hemisphere grid the start normals are profiled over, and how many of the
#: best start the full fit.
GRID_DIRECTIONS = 2000
GRID_STARTS = 3
#: Start normals closer than this (deg) count as one start.
DISTINCT_START_DEG = 0.5
#: A start whose iterate comes this close (relative to the coordinates' scale) to a minimum an
#: earlier start found is taken to end there.
SAME_MINIMUM_REL = 1e-6


class _SameMinimum(Exception):
    """A start has reached a minimum an earlier start found: it cannot win, stop it."""


class _PackedModel:
    """The signed distances and their Jacobian in the packed layout x = [t, per plane (raw
    normal v, d)], n = v / |v|: what the Levenberg-Marquardt starts evaluate some 50 times
    each, so the per-plane row indices and the constant columns are laid out once, and the
    Jacobian reuses the tips and normals of the residuals at the same x (MINPACK asks for it
    at each accepted point, the last one whose residuals it asked for).

    Most starts descend into the same minimum; their last iterations only refine digits the
    earlier start has. A start whose accepted point comes within SAME_MINIMUM_REL * scale of a
    minimum found before (t and d in mm, the normals scaled by `scale`), and no lower than the
    best cost so far allows, would end in that minimum and lose the tie: it is stopped there
    (raising _SameMinimum), which leaves the least-cost minimum, and so the solution, as is.
    """

    def __init__(self, touches: PlaneTouches, scale: float) -> None:
        self.R = touches.R
        self.f = touches.f
        self.plane = touches.plane
        self.k = len(touches.labels)
        self.scale = scale
        # one plane: every row, as a view rather than a gather
        self.rows: list[NDArray[np.intp] | slice] = (
            [slice(None)]
            if self.k == 1
            else [np.flatnonzero(touches.plane == j) for j in range(self.k)]
        )
        self.template = np.zeros((touches.R.shape[0], 3 + 4 * self.k))
        for j, rows in enumerate(self.rows):
            self.template[rows, 6 + 4 * j] = -1.0
        # unpacked [t, scale * normals, offsets] of the finished starts, one a row
        self.minima = np.empty((0, 3 + 4 * self.k))
        self.floor = -math.inf  # a start below this cost may still win
        self._key = b""
        self._parts: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None
        self._jac_key = b""
        self._jac = self.template

    def _evaluate(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(normals (K, 3), |raw normals| (K,), tips (N, 3), residuals (N,)) at x."""
        key = x.tobytes()
        if key != self._key or self._parts is None:
            rest = x[3:].reshape(self.k, 4)
            raw = rest[:, :3]
            raw_norms = np.sqrt(np.add.reduce(raw * raw, axis=1))
            normals = raw / raw_norms[:, None]
            tips = self.f + self.R @ x[:3]
            res = np.einsum("ij,ij->i", normals[self.plane], tips) - rest[:, 3][self.plane]
            self._key, self._parts = key, (normals, raw_norms, tips, res)
        return self._parts

    def residuals(self, x: FloatArray) -> FloatArray:
        """Signed distance (mm) of each tip from its plane: (N,); read only (MINPACK copies it)."""
        return self._evaluate(x)[3]

    def jacobian(self, x: FloatArray) -> FloatArray:
        """d r / d x: (N, 3 + 4K); read only (MINPACK copies it)."""
        key = x.tobytes()
        if key == self._jac_key:  # leastsq checks it at x0, then MINPACK asks again
            return self._jac
        normals, raw_norms, tips, res = self._evaluate(x)
        if self.minima.shape[0] and float(res @ res) >= self.floor:
            here = np.concatenate([x[:3], self.scale * normals.ravel(), x[6::4]])
            if float(np.abs(self.minima - here).max(axis=1).min()) <= SAME_MINIMUM_REL * self.scale:
                raise _SameMinimum
        jac = self.template.copy()
        jac[:, :3] = np.einsum("nji,nj->ni", self.R, normals[self.plane])
        for j, rows in enumerate(self.rows):
            n = normals[j]
            q = tips[rows]
            jac[rows, 3 + 4 * j : 6 + 4 * j] = (q - (q @ n)[:, None] * n) / raw_norms[j]
        self._jac_key, self._jac = key, jac
        return jac

    def finished(self, x: FloatArray, best_cost: float) -> None:
        """Record a start's minimum x; best_cost: the least cost found so far."""
        normals = self._evaluate(x)[0]
        here = np.concatenate([x[:3], self.scale * normals.ravel(), x[6::4]])
        self.minima = np.vstack([self.minima, here])
        self.floor = best_cost - 1e-12 * self.scale**2


def _linear_given_normals(touches: PlaneTouches, normals: FloatArray) -> FloatArray | None:
    """(t, d_k) by linear least squares with the normals held: x in the packed layout."""
    k = normals.shape[0]
    n_touch = touches.R.shape[0]
    A = np.zeros((n_touch, 3 + k))
    A[:, :3] = np.einsum("nji,nj->ni", touches.R, normals[touches.plane])
    A[np.arange(n_touch), 3 + touches.plane] = -1.0
    b = -np.einsum("ij,ij->i", normals[touches.plane], touches.f)
    sol, _, rank, _ = np.linalg.lstsq(A, b, rcond=None)
    if rank < A.shape[1]:
        return None
    x = np.concatenate([sol[:3], np.column_stack([normals, sol[3:]]).ravel()])
    return x


def _plane_through(points: FloatArray) -> FloatArray:
    """The unit normal of the plane best fitted to (m, 3) points."""
    _, _, vt = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)
    normal: FloatArray = vt[-1]
    return normal


def _start_normals(touches: PlaneTouches, t0: FloatArray) -> list[FloatArray]:
    """Candidate normals (K, 3): the planes through the tips under t0, and the mean flange
    axes (a tool held roughly normal to the plane has its axis near one of them)."""
    k = len(touches.labels)
    tips = touches.f + touches.R @ t0
    fitted = np.array([_plane_through(tips[touches.plane == j]) for j in range(k)])
    candidates = [fitted]
    for axis in range(3):
        per_plane = []
        for j in range(k):
            mean_axis = touches.R[touches.plane == j][:, :, axis].mean(axis=0)
            norm_ = float(np.linalg.norm(mean_axis))
            per_plane.append(mean_axis / norm_ if norm_ > 1e-6 else fitted[j])
        candidates.append(np.array(per_plane))
    # Profiled over a grid of directions: for each normal, (t, d) by linear least squares on
    # that plane's own touches; the best few directions per plane start the full fit too
    # (a tool held at small tilts leaves shallow valleys the starts above may miss).
    best = [
        _grid_normals(touches.R[touches.plane == j], touches.f[touches.plane == j])
        for j in range(k)
    ]
    for rank in range(GRID_STARTS):
        candidates.append(
            np.array([b[rank] if len(b) > rank else fitted[j] for j, b in enumerate(best)])
        )
    return _distinct(candidates)


def _distinct(candidates: list[FloatArray]) -> list[FloatArray]:
    """The candidates less those within DISTINCT_START_DEG (every plane) of an earlier one:
    they would descend into the same valley."""
    cos_limit = math.cos(math.radians(DISTINCT_START_DEG))
    kept: list[FloatArray] = []
    for normals in candidates:
        if not any(np.all(np.abs(np.sum(normals * k, axis=1)) >= cos_limit) for k in kept):
            kept.append(normals)
    return kept


@lru_cache(maxsize=4)
def _hemisphere(count: int) -> tuple[FloatArray, FloatArray]:
    """About `count` unit vectors n spread evenly over the upper half sphere (Fibonacci), and
    their outer products n n^T flattened (count, 9); read-only (shared by every solve)."""
    i = np.arange(count) + 0.5
    z = 1.0 - i / count
    r = np.sqrt(1.0 - z**2)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    normals: FloatArray = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    outer: FloatArray = (normals[:, :, None] * normals[:, None, :]).reshape(count, 9)
    normals.flags.writeable = False
    outer.flags.writeable = False
    return normals, outer


def _grid_normals(R: FloatArray, f: FloatArray) -> list[FloatArray]:
    """The GRID_STARTS distinct directions of the hemisphere grid with the least profiled cost (one
    plane's touches R (m, 3, 3), f (m, 3)); none when they are too few to profile.

    Per direction n: rows A_i = [R_i^T n, -1], b_i = -n . f_i; the normal equations and the
    residual sum come from sums over the touches taken once (O(m) + O(grid), not O(m grid)).
    """
    m = R.shape[0]
    if m < 5:
        return []
    normals, outer = _hemisphere(GRID_DIRECTIONS)
    S = np.einsum("ica,idb->cdab", R, R)  # sum_i R_i[c, a] R_i[d, b]
    T = np.einsum("ica,id->cda", R, f)  # sum_i R_i[c, a] f_i[d]
    F = f.T @ f
    AtA = np.empty((normals.shape[0], 4, 4))
    AtA[:, :3, :3] = (outer @ S.reshape(9, 9)).reshape(-1, 3, 3)
    AtA[:, :3, 3] = AtA[:, 3, :3] = -normals @ R.sum(axis=0)
    AtA[:, 3, 3] = m
    Atb = np.empty((normals.shape[0], 4))
    Atb[:, :3] = -(outer @ T.reshape(9, 3))
    Atb[:, 3] = normals @ f.sum(axis=0)
    btb = np.sum((normals @ F) * normals, axis=1)
    well, cost = _profiled_costs(AtA, Atb, btb, 1e12)
    if not well.any():
        return []
    candidates = normals[well]
    cos_limit = math.cos(math.radians(DISTINCT_START_DEG))
    chosen: list[FloatArray] = []
    for i in np.argsort(cost):
        n = candidates[i]
        if all(abs(float(n @ c)) < cos_limit for c in chosen):
            chosen.append(n)
            if len(chosen) == GRID_STARTS:
                break
    return chosen


def _profiled_costs(
    AtA: FloatArray, Atb: FloatArray, btb: FloatArray, limit: float
) -> tuple[NDArray[np.bool_], FloatArray]:
    """Which of a stack of normal equations (G, 4, 4) are well conditioned
    (np.linalg.cond < limit), and for those the least-squares residual sum b'b - b'A x.

    Without an SVD and an LU solve of each (the grid's 2000 were a third of a solve): with
    AtA = L L^T (Cholesky), cond = |AtA|_2 |L^-1|_2^2 lies within a factor 8 below
    P = |AtA|_F |L^-1|_F^2 (the Frobenius norm of a 4x4 is at most twice the 2-norm), so
    P < limit / 4 is well and P > 32 limit ill-conditioned beyond rounding (the SVD decides
    the few in between), and the residual sum is b'b - |L^-1 A'b|^2. A stack Cholesky cannot
    factor takes the SVD and LU way throughout.
    """
    try:
        chol = np.asarray(np.linalg.cholesky(AtA), dtype=np.float64)
    except np.linalg.LinAlgError:
        well: NDArray[np.bool_] = np.linalg.cond(AtA) < limit
        sol = np.linalg.solve(AtA[well], Atb[well][..., None])[..., 0]
        return well, btb[well] - np.einsum("gi,gi->g", Atb[well], sol)
    inv = _triangular_inverse(chol)
    p = np.sqrt(np.einsum("gij,gij->g", AtA, AtA)) * np.einsum("gij,gij->g", inv, inv)
    well = p < limit / 4.0
    unsure = ~well & ~(p > 32.0 * limit)
    if unsure.any():
        well[unsure] = np.linalg.cond(AtA[unsure]) < limit
    y = np.einsum("gij,gj->gi", inv[well], Atb[well])
    cost: FloatArray = btb[well] - np.sum(y * y, axis=1)
    return well, cost


def _triangular_inverse(low: FloatArray) -> FloatArray:
    """L^-1 for a stack of lower-triangular 4x4 L, by forward substitution (G, 4, 4)."""
    inv = np.zeros_like(low)
    for i in range(4):
        inv[:, i, i] = 1.0 / low[:, i, i]
        for j in range(i):
            inv[:, i, j] = -np.einsum("gk,gk->g", low[:, i, j:i], inv[:, j:i, j]) / low[:, i, i]
    return inv


def fit_planes(touches: PlaneTouches, t0: FloatArray) -> FloatArray:
    """The packed solution of least cost over the starts."""
    best: FloatArray | None = None
    best_cost = math.inf
    scale = max(1.0, float(np.abs(touches.f).max()))
    model = _PackedModel(touches, scale)
    for normals in _start_normals(touches, t0):
        x0 = _linear_given_normals(touches, normals)
        if x0 is None:
            continue
        try:
            x = _levenberg_marquardt(model.residuals, model.jacobian, x0, touches.R.shape[0])
        except _SameMinimum:
            continue
        cost = float(np.sum(model.residuals(x) ** 2))
        if cost < best_cost - 1e-12 * scale**2:
            best, best_cost = x, cost
        model.finished(x, best_cost)
    if best is None:
        raise InvalidInput(
            "degenerate-poses",
            "the touches do not determine the TCP and the planes together; touch with the tool "
            "tilted in different directions, at points spread across each plane",
            loc=("poses",),
        )
    return _polish(touches, best)


def _levenberg_marquardt(
    fun: Callable[[FloatArray], FloatArray],
    jac: Callable[[FloatArray], FloatArray],
    x0: FloatArray,
    n_residuals: int,
) -> FloatArray:
    """MINPACK's Levenberg-Marquardt (lmder) from x0, scaled by the Jacobian's columns.

    "lm" needs at least as many residuals as unknowns (the normals carry one spare coordinate
    each, the scale, which the residuals do not see); "trf" copes either way. The "lm" case
    calls MINPACK through leastsq, the same iterations as least_squares(method="lm",
    x_scale="jac") without its per-call wrappers (most of the time of a small fit).
    """
    # scipy.optimize costs a few hundred ms to import: every tcpcal process imports this module,
    # only solvers fit (their forkserver imports it up front: app.main.SOLVER_PRELOAD)
    from scipy.optimize import least_squares, leastsq

    tol = 1e-8
    if n_residuals < x0.size:
        fit = least_squares(
            fun, x0, jac=jac, method="trf", x_scale="jac", xtol=tol, ftol=tol, gtol=tol
        )
        return np.asarray(fit.x, dtype=np.float64)
    x, *_ = leastsq(
        fun, x0, Dfun=jac, full_output=True, xtol=tol, ftol=tol, gtol=tol, maxfev=100 * x0.size
    )
    return np.asarray(x, dtype=np.float64)


def _polish(touches: PlaneTouches, x: FloatArray) -> FloatArray:
    """Gauss-Newton steps in the tangent coordinates, to the last digit (noise-free data
    then comes back exact to rounding)."""
    k = len(touches.labels)
    for _ in range(5):
        t, normals, offsets = unpack(x, k)
        r = signed_distances(touches, t, normals, offsets)
        jac = distance_jacobian(touches, t, normals)
        step, *_ = np.linalg.lstsq(jac, -r, rcond=None)
        t_new = t + step[:3]
        rows = []
        for j in range(k):
            e1, e2 = tangents(normals[j])
            n_new = normals[j] + step[3 + 3 * j] * e1 + step[4 + 3 * j] * e2
            rows.append(
                np.concatenate([n_new / np.linalg.norm(n_new), [offsets[j] + step[5 + 3 * j]]])
            )
        x_new = np.concatenate([t_new, np.ravel(rows)])
        t2, n2, d2 = unpack(x_new, k)
        if np.sum(signed_distances(touches, t2, n2, d2) ** 2) > np.sum(r**2):
            break
        x = x_new
        if float(np.abs(step).max()) < 1e-13 * max(1.0, float(np.abs(x).max())):
            break
    return x
