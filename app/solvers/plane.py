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
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares, leastsq
from scipy.stats import chi2, norm
from scipy.stats import f as f_dist
from scipy.stats import t as student_t

from app.errors import InvalidInput
from app.solvers.quality import (
    ELLIPSOID_PROBABILITY,
    SIGMA_CONFIGURED,
    SIGMA_RESIDUALS,
    Quality,
    SigmaSource,
    format_vector,
    make_quality,
    orientation_spread_deg,
)
from app.solvers.validation import MAX_ABS_MM, check_positions_mm, check_rotation_matrices

FloatArray = NDArray[np.float64]

#: Labels of the planes one submission may touch (API: `"plane": "a" | "b" | "c"`).
PLANE_LABELS = ("a", "b", "c")
#: Fewest touches of one plane: 3 unknowns for the TCP and 3 for the plane, and one more:
#: with exactly as many touches as unknowns the distances vanish at several solutions (about
#: half of 200 seeded exact 6-touch sets gave another exact one), nothing tells them apart.
MIN_POSES = 7
#: Fewest touches on each plane (its normal and offset are 3 unknowns).
MIN_PER_PLANE = 3
#: All orientations within this angle (deg) of each other: the touches only translate.
TRANSLATION_ONLY_DEG = 0.5
#: Refuse when s_min / s_max of the centred rotation block [R_i - mean(R)] is below this: the
#: touches rotate (almost) about one flange axis.
DEGENERACY_RATIO = 1e-2
#: Warn when that ratio is below this (one rotation axis dominates).
WEAK_DIRECTION_RATIO = 0.1
#: A rotation axis within this angle (deg) of the plane's normal or of flange z is named so.
AXIS_MATCH_DEG = 5.0
#: The tips on a plane must spread at least this much (rms, mm) across their main direction.
MIN_TIP_SPREAD_MM = 1.0
#: Directions of the hemisphere grid the start normals are profiled over, and how many of the
#: best start the full fit.
GRID_DIRECTIONS = 2000
GRID_STARTS = 3
#: Start normals closer than this (deg) count as one start.
DISTINCT_START_DEG = 0.5
#: A start whose iterate comes this close (relative to the coordinates' scale) to a minimum an
#: earlier start found is taken to end there.
SAME_MINIMUM_REL = 1e-6
#: Refuse when the Jacobian's scaled condition number exceeds this (no unique solution).
MAX_CONDITION = 1e12
#: Below this many degrees of freedom an estimated touch noise is flagged as soft.
FEW_DOF = 6
#: Significance level at which the touches must show a TCP away from the flange centre.
SHOWN_ALPHA = 1e-3
#: Residuals below this (mm) are rounding: an exact fit.
RESIDUAL_FLOOR_MM = 1e-9


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


@dataclass(frozen=True)
class _Touches:
    R: FloatArray  # (N, 3, 3)
    f: FloatArray  # (N, 3)
    plane: NDArray[np.intp]  # (N,) index into labels
    labels: tuple[str, ...]


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
    touches = _checked(rotations, positions_mm, planes, touch_noise_mm)
    spread_deg = _check_orientations(touches)
    x = _fit(touches, _start_tcp(start_tcp_mm))
    t, normals, offsets = _unpack(x, len(touches.labels))
    _check_bounded(t, offsets)
    _check_tip_spread(touches, t)
    residuals = _residuals(touches, t, normals, offsets)
    jac = _jacobian(touches, t, normals)
    unit_cov = _unit_covariance(jac)
    n, p = jac.shape
    dof = n - p
    _check_tcp_shown(touches, residuals, dof, touch_noise_mm)
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
    touches = _Touches(
        R=R,
        f=np.asarray(positions_mm, dtype=np.float64),
        plane=np.array([labels.index(lab) for lab in given], dtype=np.intp),
        labels=labels,
    )
    jac = _jacobian(
        touches, np.asarray(tcp_mm, dtype=np.float64), np.asarray(normals, dtype=np.float64)
    )
    bound = touch_noise_mm**2 * np.linalg.inv(jac.T @ jac)[:3, :3]
    return np.asarray(bound, dtype=np.float64)


# ---------------------------------------------------------------------------- input checks


def _checked(
    rotations: ArrayLike,
    positions_mm: ArrayLike,
    planes: Sequence[str] | None,
    touch_noise_mm: float | None,
) -> _Touches:
    R = check_rotation_matrices(rotations, loc=("poses",))
    f = check_positions_mm(positions_mm, loc=("poses",))
    n = R.shape[0]
    if f.shape[0] != n:
        raise InvalidInput(
            "invalid-pose",
            f"got {n} rotations but {f.shape[0]} positions; each touch needs both",
            loc=("poses",),
        )
    given = ["a"] * n if planes is None else list(planes)
    if len(given) != n:
        raise InvalidInput(
            "invalid-pose", f"{len(given)} plane labels for {n} touches", loc=("poses",)
        )
    labels = tuple(sorted(set(given)))
    unknown = [lab for lab in labels if lab not in PLANE_LABELS]
    if unknown:
        raise InvalidInput(
            "invalid-pose",
            f"unknown plane label {unknown[0]!r}: touches name plane 'a', 'b' or 'c'",
            loc=("poses", given.index(unknown[0]), "plane"),
        )
    index = np.array([labels.index(lab) for lab in given], dtype=np.intp)
    unknowns = 3 + 3 * len(labels)
    if n <= unknowns:
        raise InvalidInput(
            "too-few-poses",
            f"{n} touches given; {len(labels)} plane(s) and the TCP are {unknowns} unknowns, so "
            f"at least {unknowns + 1} touches are needed: {unknowns} touches fit exactly, and "
            "such a fit has several exact solutions (and nothing checks the touches against "
            "each other); one more touch makes it unique",
            loc=("poses",),
            context={"n_poses": n, "min_poses": unknowns + 1},
        )
    for k, lab in enumerate(labels):
        m = int(np.sum(index == k))
        if m < MIN_PER_PLANE:
            first = int(np.flatnonzero(index == k)[0])
            raise InvalidInput(
                "too-few-poses",
                f"plane {lab!r} has {m} touch(es); a plane needs at least {MIN_PER_PLANE} "
                "(its tilt and offset are 3 unknowns): touch it more, at points spread across it",
                loc=("poses", first, "plane"),
                context={"plane": lab, "n_touches": m, "min_touches": MIN_PER_PLANE},
            )
    return _Touches(R=R, f=f, plane=index, labels=labels)


def _start_tcp(start_tcp_mm: ArrayLike | None) -> FloatArray:
    if start_tcp_mm is None:
        return np.zeros(3)
    t = np.asarray(start_tcp_mm, dtype=np.float64).reshape(3)
    return t if np.all(np.isfinite(t)) else np.zeros(3)


def _check_orientations(touches: _Touches) -> float:
    """Refuse touches whose orientations cannot tell the TCP from the planes' offsets; the
    orientation spread (deg) of those accepted."""
    R = touches.R
    spread = orientation_spread_deg(R)
    if spread < TRANSLATION_ONLY_DEG:
        raise InvalidInput(
            "degenerate-poses",
            f"the touches only translate (every orientation within {spread:.2g} deg of the "
            "others): moving the tool without turning it shifts the tip and the plane alike, "
            "so the TCP cannot be found; touch with the tool tilted in different directions "
            "(rotations about at least two different axes, 15-40 deg from the plane's normal)",
            loc=("poses",),
            context={"orientation_spread_deg": spread},
        )
    ratio, axis = _rotation_block(R)
    if ratio >= DEGENERACY_RATIO:
        return spread
    base_axis = R[0] @ axis
    context = {"direction_flange": [float(v) for v in axis], "singular_value_ratio": ratio}
    if _parallel(base_axis, _flange_plane_normal(touches)):
        raise InvalidInput(
            "degenerate-poses",
            "the touches only spin the tool about the plane's normal (base direction "
            f"{format_vector(_canonical(base_axis))}): every touch sees the plane alike and the "
            "TCP cannot be found; tilt the tool relative to the plane between touches, in at "
            "least two different directions",
            loc=("poses",),
            context=context,
        )
    if _parallel(axis, np.array([0.0, 0.0, 1.0])):
        what = "all touches have parallel tool axes (they only turn about flange z)"
    else:
        what = f"the touches only rotate about one flange axis {format_vector(axis)}"
    raise InvalidInput(
        "degenerate-poses",
        f"{what}: the TCP along that axis moves every touch's distance to the plane equally and "
        "cannot be told from the plane's offset; tilt the tool about another axis between "
        f"touches (vary the direction of the flange axis {format_vector(axis)})",
        loc=("poses",),
        context=context,
    )


def _rotation_block(R: FloatArray) -> tuple[float, FloatArray]:
    """s_min / s_max of the centred block [R_i - mean(R)] and its weakest direction (flange)."""
    Cs = (R - R.mean(axis=0)).reshape(-1, 3)
    evals, evecs = np.linalg.eigh(Cs.T @ Cs)
    top = float(evals[-1])
    ratio = math.sqrt(max(float(evals[0]), 0.0) / top) if top > 0.0 else 0.0
    return ratio, _canonical(evecs[:, 0])


def _flange_plane_normal(touches: _Touches) -> FloatArray | None:
    """The normal of the plane best fitted to the flange positions of the first plane's
    touches, when they spread in two directions (spins about the normal keep them on a plane)."""
    f = touches.f[touches.plane == 0]
    centred = f - f.mean(axis=0)
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    if s.size < 2 or s[1] < MIN_TIP_SPREAD_MM * math.sqrt(f.shape[0]):
        return None
    normal: FloatArray = vt[-1]
    return normal


def _parallel(a: FloatArray, b: FloatArray | None) -> bool:
    if b is None:
        return False
    cos = abs(float(a @ b)) / (float(np.linalg.norm(a)) * float(np.linalg.norm(b)))
    return cos >= math.cos(math.radians(AXIS_MATCH_DEG))


def _canonical(v: FloatArray) -> FloatArray:
    u = np.asarray(v, dtype=np.float64) / float(np.linalg.norm(v))
    if u[int(np.argmax(np.abs(u)))] < 0:
        u = -u
    return u + 0.0  # no negative zeros in messages


def _check_tip_spread(touches: _Touches, t: FloatArray) -> None:
    """Refuse a plane whose touched points (tips under the fitted TCP t) sit at one spot or
    along one line: the plane's tilt about that line is free, and the fit means nothing."""
    tips = touches.f + touches.R @ t
    for k, label in enumerate(touches.labels):
        q = tips[touches.plane == k]
        centred = q - q.mean(axis=0)
        s = np.linalg.svd(centred, compute_uv=False)
        minor = float(s[1]) / math.sqrt(q.shape[0]) if s.size > 1 else 0.0
        if minor < MIN_TIP_SPREAD_MM:
            raise _spot_refusal(label, minor, touches)


def _check_tcp_shown(
    touches: _Touches, residuals: FloatArray, dof: int, touch_noise_mm: float | None
) -> None:
    """Refuse when the flange positions alone fit the planes about as well as the tips do:
    then a TCP at the flange centre explains the touches, and they show no TCP at all.

    It happens whenever R_i t has one component along the normal for every touch (the tool
    axes all parallel, pure translations), whatever the rotations read: so it also keeps a
    misread set of such touches from fitting "well" with t = 0 (the convention diagnosis
    then finds no reading that fits, and the refusal names the missing tilt). Test: the three
    TCP coordinates must lower the sum of squares significantly (F, or chi2 with a
    configured noise, at 0.1 %).
    """
    ssr = float(np.sum(residuals**2))
    ssr_flange = 0.0
    for k in range(len(touches.labels)):
        f = touches.f[touches.plane == k]
        s = np.linalg.svd(f - f.mean(axis=0), compute_uv=False)
        ssr_flange += float(s[-1] ** 2)
    gain = ssr_flange - ssr
    if touch_noise_mm is not None:
        shown = gain > _chi2_quantile(1.0 - SHOWN_ALPHA, 3) * touch_noise_mm**2
    else:
        shown = gain > 3.0 * _f_quantile(1.0 - SHOWN_ALPHA, 3, dof) * ssr / dof
    floor = (RESIDUAL_FLOOR_MM**2) * touches.R.shape[0]
    if shown and gain > floor:
        return
    raise InvalidInput(
        "degenerate-poses",
        "the flange positions alone lie on the plane(s) as closely as the touches do: a TCP at "
        "the flange centre explains these touches, so they do not show the TCP (the tool axis "
        "kept parallel, or pure translations); touch with the tool tilted in different "
        "directions, 15-40 deg from the plane's normal",
        loc=("poses",),
        context={"rms_flange_mm": math.sqrt(ssr_flange / touches.R.shape[0])},
    )


def _spot_refusal(label: str, minor: float, touches: _Touches) -> InvalidInput:
    first = int(np.flatnonzero(touches.labels.index(label) == touches.plane)[0])
    return InvalidInput(
        "degenerate-poses",
        f"the touches of plane {label!r} lie at one spot or along one line (spread "
        f"{minor:.2g} mm across it): the plane's tilt about that line is free, and with it the "
        "TCP; touch points spread across the plane in two directions (tens of mm apart), or "
        "touch one fixed point with xyz_npoint",
        loc=("poses", first),
        context={"plane": label, "spread_mm": minor},
    )


# ------------------------------------------------------------------------------- the model


def _unpack(x: FloatArray, k: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """x = [t (3), then per plane (nx, ny, nz, d)] -> t, normals (K, 3) unit, offsets (K,)."""
    t = x[:3]
    rest = x[3:].reshape(k, 4)
    normals = rest[:, :3] / np.linalg.norm(rest[:, :3], axis=1, keepdims=True)
    return t, normals, rest[:, 3]


def _residuals(
    touches: _Touches, t: FloatArray, normals: FloatArray, offsets: FloatArray
) -> FloatArray:
    """Signed distance (mm) of each tip from its plane."""
    tips = touches.f + touches.R @ t
    n = normals[touches.plane]
    out: FloatArray = np.einsum("ij,ij->i", n, tips) - offsets[touches.plane]
    return out


def _tangents(normal: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors completing `normal` to a right-handed orthonormal basis."""
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    e1 = _cross(normal, helper)
    e1 /= np.linalg.norm(e1)
    return e1, _cross(normal, e1)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """a x b of two 3-vectors: np.cross's products and differences, without its overhead."""
    a0, a1, a2 = (float(v) for v in a)
    b0, b1, b2 = (float(v) for v in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _jacobian(touches: _Touches, t: FloatArray, normals: FloatArray) -> FloatArray:
    """d r / d (t, per plane: tangent a, tangent b, d) at (t, normals): (N, 3 + 3K).

    A normal moves as n + a e1 + b e2 (normalised), so d r_i / d(a, b) = (e1, e2) . tip_i.
    """
    k = normals.shape[0]
    n_touch = touches.R.shape[0]
    tips = touches.f + touches.R @ t
    jac = np.zeros((n_touch, 3 + 3 * k))
    jac[:, :3] = np.einsum("nji,nj->ni", touches.R, normals[touches.plane])
    for j in range(k):
        rows = touches.plane == j
        e1, e2 = _tangents(normals[j])
        jac[rows, 3 + 3 * j] = tips[rows] @ e1
        jac[rows, 4 + 3 * j] = tips[rows] @ e2
        jac[rows, 5 + 3 * j] = -1.0
    return jac


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

    def __init__(self, touches: _Touches, scale: float) -> None:
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


def _linear_given_normals(touches: _Touches, normals: FloatArray) -> FloatArray | None:
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


def _start_normals(touches: _Touches, t0: FloatArray) -> list[FloatArray]:
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


def _fit(touches: _Touches, t0: FloatArray) -> FloatArray:
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


def _polish(touches: _Touches, x: FloatArray) -> FloatArray:
    """Gauss-Newton steps in the tangent coordinates, to the last digit (noise-free data
    then comes back exact to rounding)."""
    k = len(touches.labels)
    for _ in range(5):
        t, normals, offsets = _unpack(x, k)
        r = _residuals(touches, t, normals, offsets)
        jac = _jacobian(touches, t, normals)
        step, *_ = np.linalg.lstsq(jac, -r, rcond=None)
        t_new = t + step[:3]
        rows = []
        for j in range(k):
            e1, e2 = _tangents(normals[j])
            n_new = normals[j] + step[3 + 3 * j] * e1 + step[4 + 3 * j] * e2
            rows.append(
                np.concatenate([n_new / np.linalg.norm(n_new), [offsets[j] + step[5 + 3 * j]]])
            )
        x_new = np.concatenate([t_new, np.ravel(rows)])
        t2, n2, d2 = _unpack(x_new, k)
        if np.sum(_residuals(touches, t2, n2, d2) ** 2) > np.sum(r**2):
            break
        x = x_new
        if float(np.abs(step).max()) < 1e-13 * max(1.0, float(np.abs(x).max())):
            break
    return x


def _check_bounded(t: FloatArray, offsets: FloatArray) -> None:
    if (
        not (np.all(np.isfinite(t)) and np.all(np.isfinite(offsets)))
        or float(np.abs(t).max()) > MAX_ABS_MM
        or float(np.abs(offsets).max()) > 10 * MAX_ABS_MM
    ):
        raise InvalidInput(
            "degenerate-poses",
            "the touches do not determine the TCP (the solution is unbounded); touch with the "
            "tool tilted in different directions, about at least two axes",
            loc=("poses",),
        )


# ----------------------------------------------------------------------------- uncertainty


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
def _chi2_quantile(q: float, dof: int) -> float:
    return float(chi2.ppf(q, dof))


@lru_cache(maxsize=256)
def _f_quantile(q: float, dfn: int, dfd: int) -> float:
    return float(f_dist.ppf(q, dfn, dfd))


@lru_cache(maxsize=256)
def widening(dof: float) -> float:
    """t(0.975, dof) / 1.96: keeps +-1.96 sigma a 95 % interval when the noise behind sigma
    was estimated on dof degrees of freedom."""
    return float(student_t.ppf(0.975, dof) / norm.ppf(0.975))


def _ellipsoid_scale(dof: int | None) -> float:
    """k with (x - x^)^T Cov^-1 (x - x^) <= k^2 95 % of the time in 3-D: chi2 with a known
    noise, Hotelling's 3 F(3, dof) with one estimated on dof degrees of freedom."""
    if dof is None:
        return math.sqrt(_chi2_quantile(ELLIPSOID_PROBABILITY, 3))
    return math.sqrt(3.0 * _f_quantile(ELLIPSOID_PROBABILITY, 3, dof))


def check_predicted_sigma(
    cov_t: FloatArray, max_tcp_sigma_mm: float, noise: float, configured: bool
) -> None:
    """Refuse ("insufficient-spread") when the TCP's 1-sigma (cov_t, 3x3 mm^2) along its
    weakest direction exceeds max_tcp_sigma_mm; noise: the touch noise behind cov_t."""
    evals, evecs = np.linalg.eigh(0.5 * (cov_t + cov_t.T))
    worst = math.sqrt(max(float(evals[-1]), 0.0))
    if worst <= max_tcp_sigma_mm:
        return
    direction = _canonical(evecs[:, -1])
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
    touches: _Touches, normals: FloatArray, offsets: FloatArray, cov: FloatArray
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
    touches: _Touches,
    residuals: FloatArray,
    dof: int,
    noise: float,
    touch_noise_mm: float | None,
) -> list[str]:
    warnings = []
    ratio, axis = _rotation_block(touches.R)
    if ratio < WEAK_DIRECTION_RATIO:
        warnings.append(
            f"the touches turn mostly about the flange axis {format_vector(axis)} (singular "
            f"value ratio {ratio:.3f}): the TCP along it is weakly determined; tilt the tool "
            "about another axis"
        )
    if touch_noise_mm is not None:
        chi2_stat = float(np.sum(residuals**2)) / touch_noise_mm**2
        if chi2_stat > _chi2_quantile(1.0 - 1e-3, dof):
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
