"""Input checks of the xyz_plane method: the touches and labels, orientations that can tell the
TCP from the planes' offsets, tips spread across each plane, a TCP the touches show.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.distributions import chi2_ppf, f_ppf
from app.solvers.plane.model import PlaneTouches
from app.solvers.quality import (
    format_vector,
    orientation_spread_deg,
)
from app.solvers.validation import MAX_ABS_MM, check_positions_mm, check_rotation_matrices

#: Labels of the planes one submission may touch (API: `"plane": "a" | "b" | "c"`).
PLANE_LABELS = ("a", "b", "c")
#: Fewest touches on each plane (its normal and offset are 3 unknowns).
MIN_PER_PLANE = 3
#: All orientations within this angle (deg) of each other: the touches only translate.
TRANSLATION_ONLY_DEG = 0.5
#: Refuse when s_min / s_max of the centred rotation block [R_i - mean(R)] is below this: the
#: touches rotate (almost) about one flange axis.
DEGENERACY_RATIO = 1e-2
#: A rotation axis within this angle (deg) of the plane's normal or of flange z is named so.
AXIS_MATCH_DEG = 5.0
#: The tips on a plane must spread at least this much (rms, mm) across their main direction.
MIN_TIP_SPREAD_MM = 1.0
#: Significance level at which the touches must show a TCP away from the flange centre.
SHOWN_ALPHA = 1e-3
#: Residuals below this (mm) are rounding: an exact fit.
RESIDUAL_FLOOR_MM = 1e-9


def checked_touches(
    rotations: ArrayLike,
    positions_mm: ArrayLike,
    planes: Sequence[str] | None,
    touch_noise_mm: float | None,
) -> PlaneTouches:
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
    return PlaneTouches(R=R, f=f, plane=index, labels=labels)


def start_tcp(start_tcp_mm: ArrayLike | None) -> FloatArray:
    if start_tcp_mm is None:
        return np.zeros(3)
    t = np.asarray(start_tcp_mm, dtype=np.float64).reshape(3)
    return t if np.all(np.isfinite(t)) else np.zeros(3)


def check_orientations(touches: PlaneTouches) -> float:
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
    ratio, axis = rotation_block(R)
    if ratio >= DEGENERACY_RATIO:
        return spread
    base_axis = R[0] @ axis
    context = {"direction_flange": [float(v) for v in axis], "singular_value_ratio": ratio}
    if _parallel(base_axis, _flange_plane_normal(touches)):
        raise InvalidInput(
            "degenerate-poses",
            "the touches only spin the tool about the plane's normal (base direction "
            f"{format_vector(canonical(base_axis))}): every touch sees the plane alike and the "
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


def rotation_block(R: FloatArray) -> tuple[float, FloatArray]:
    """s_min / s_max of the centred block [R_i - mean(R)] and its weakest direction (flange)."""
    Cs = (R - R.mean(axis=0)).reshape(-1, 3)
    evals, evecs = np.linalg.eigh(Cs.T @ Cs)
    top = float(evals[-1])
    ratio = math.sqrt(max(float(evals[0]), 0.0) / top) if top > 0.0 else 0.0
    return ratio, canonical(evecs[:, 0])


def _flange_plane_normal(touches: PlaneTouches) -> FloatArray | None:
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


def canonical(v: FloatArray) -> FloatArray:
    u = np.asarray(v, dtype=np.float64) / float(np.linalg.norm(v))
    if u[int(np.argmax(np.abs(u)))] < 0:
        u = -u
    return u + 0.0  # no negative zeros in messages


def check_tip_spread(touches: PlaneTouches, t: FloatArray) -> None:
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


def check_tcp_shown(
    touches: PlaneTouches, residuals: FloatArray, dof: int, touch_noise_mm: float | None
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
        shown = gain > chi2_quantile(1.0 - SHOWN_ALPHA, 3) * touch_noise_mm**2
    else:
        shown = gain > 3.0 * f_quantile(1.0 - SHOWN_ALPHA, 3, dof) * ssr / dof
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


def _spot_refusal(label: str, minor: float, touches: PlaneTouches) -> InvalidInput:
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


def check_bounded(t: FloatArray, offsets: FloatArray) -> None:
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


@lru_cache(maxsize=256)
def chi2_quantile(q: float, dof: int) -> float:
    return float(chi2_ppf(q, dof))


@lru_cache(maxsize=256)
def f_quantile(q: float, dfn: int, dfd: int) -> float:
    return float(f_ppf(q, dfn, dfd))
