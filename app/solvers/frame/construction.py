"""Frames constructed from role touches, as the pendants compute them (each pendant's name
for a construction is its maker's declaration, `Maker.teaches`, said by GET /v1/methods).

Every construction maps the touched points (base frame, mm) of its roles to a frame (R, o).
They are exact: three touches give no residual, so their uncertainty is the touch noise and
the pointer's TCP error carried through the construction (a numerical Jacobian of the exact
map, central differences, against the correlated point covariance of `model`).

- `three_point`, convention `origin_x_xy` (a 3-point base or user frame, the ORG/XX/XY user
  frame): the origin at the origin touch, +X through the x touch, Z = X x (xy - origin),
  Y = Z x X (METHODS.md 7).
- `three_point`, convention `abb_user` (X1, X2 on the X axis, Y1 on the Y axis): RAPID's
  DefFrame(X1, X2, Y1 \\Origin:=3), "Technical reference manual - RAPID Instructions,
  Functions and Data types" (3HAC16581-1), DefFrame: "Origin = 3 means
  that the origin is placed on the line going through NewP1 and NewP2 and so that NewP3 will
  be placed on the y axis"; X from X1 towards X2, Y towards Y1.
- `three_point`, convention `ur_plane` (PolyScope's Plane feature, taught by three points:
  the first is the plane's origin, the second gives +X, the third the +Y side; Z by the
  right-hand rule): the same construction as `origin_x_xy`, under the pendant's words.
- `four_point` (the four point user frame: Orient Origin Point, X Direction Point, Y
  Direction Point, System Origin): X from x_start to x, the XY plane through x_start, x and
  xy, the origin moved to the origin touch.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final, get_args

import numpy as np

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.frame.model import FrameEstimate
from app.words import ThreePointConvention

CONVENTIONS: Final[tuple[ThreePointConvention, ...]] = get_args(ThreePointConvention)
#: Two touches closer than this (mm) are one point: no direction can be taken between them.
MIN_SEPARATION_MM: Final = 1.0
#: Default refusal limit of a construction's predicted angle 1-sigma (deg), API.md v1.4.
MAX_ANGLE_SIGMA_DEG: Final = 0.05
#: Step of the numerical Jacobian, mm (the map is smooth; central differences, error ~h^2).
JACOBIAN_STEP_MM: Final = 1e-4

#: A construction: the roles' points in role order -> (R frame->base, origin mm).
Build = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


@dataclass(frozen=True)
class Construction:
    """Roles in the order they are touched, what each means in words, and the map."""

    roles: tuple[str, ...]
    words: Mapping[str, str]
    build: Build
    #: the role whose distance from `axis_from` sets the X axis' angle error
    x_role: str
    axis_from: str
    #: the role whose distance from the X axis sets the angle error about X
    plane_role: str


def _unit(v: FloatArray) -> FloatArray:
    out: FloatArray = v / np.linalg.norm(v)
    return out


def _axes(ex: FloatArray, in_plane: FloatArray) -> FloatArray:
    ez = _unit(np.cross(ex, in_plane))
    return np.column_stack([ex, np.cross(ez, ex), ez])


def _origin_x_xy(p: FloatArray) -> tuple[FloatArray, FloatArray]:
    o, x, xy = p
    return _axes(_unit(x - o), xy - o), o.copy()


def _abb_user(p: FloatArray) -> tuple[FloatArray, FloatArray]:
    x1, x2, y1 = p
    ex = _unit(x2 - x1)
    origin = x1 + float(np.dot(y1 - x1, ex)) * ex
    return _axes(ex, y1 - origin), origin


def _four_point(p: FloatArray) -> tuple[FloatArray, FloatArray]:
    start, x, xy, origin = p
    return _axes(_unit(x - start), xy - start), origin.copy()


_WORDS = {
    "origin": "the frame's origin",
    "x": "a point on the frame's +X axis",
    "xy": "a point in the frame's XY plane, on the +Y side of the X axis",
}
THREE_POINT: Final[dict[ThreePointConvention, Construction]] = {
    "origin_x_xy": Construction(("origin", "x", "xy"), _WORDS, _origin_x_xy, "x", "origin", "xy"),
    "abb_user": Construction(
        ("x1", "x2", "y1"),
        {
            "x1": "X1, a point on the frame's X axis",
            "x2": "X2, a point farther along +X",
            "y1": "Y1, a point on the frame's +Y axis",
        },
        _abb_user,
        "x2",
        "x1",
        "y1",
    ),
    "ur_plane": Construction(
        ("origin", "x", "xy"),
        {
            "origin": "the plane's origin (PolyScope's first point)",
            "x": "a point on the plane's +X axis (the second point)",
            "xy": "a point on the plane's +Y side (the third point)",
        },
        _origin_x_xy,
        "x",
        "origin",
        "xy",
    ),
}
FOUR_POINT: Final = Construction(
    ("x_start", "x", "xy", "origin"),
    {
        "x_start": "a point on the X axis where it starts (Orient Origin Point)",
        "x": "a point farther along +X (X Direction Point)",
        "xy": "a point in the XY plane, on the +Y side (Y Direction Point)",
        "origin": "the frame's origin (System Origin)",
    },
    _four_point,
    "x",
    "x_start",
    "xy",
)


def ordered_points(
    construction: Construction,
    roles: Sequence[str],
    points: FloatArray,
    touch_index: Sequence[int] | None = None,
) -> FloatArray:
    """The touches' points (N, 3) put in the construction's role order; refuses a role
    missing, repeated or unknown, naming the touch (loc ("touches", i, "role"), i the
    touch's index in the body: `touch_index[k]` for the k-th role given, else k)."""
    seen: dict[str, int] = {}
    index = list(range(len(roles))) if touch_index is None else list(touch_index)
    for k, role in enumerate(roles):
        i = index[k]
        if role not in construction.roles:
            raise InvalidInput(
                "missing-role",
                f"touch {i + 1} has role {role!r}, which this method does not take: give each "
                f"of {', '.join(construction.roles)} once",
                loc=("touches", i, "role"),
            )
        if role in seen:
            raise InvalidInput(
                "repeated-role",
                f"touches {seen[role] + 1} and {i + 1} both have role {role!r}: each role is "
                "touched once; drop one of them",
                loc=("touches", i, "role"),
            )
        seen[role] = i
    missing = [r for r in construction.roles if r not in seen]
    if missing:
        raise InvalidInput(
            "missing-role",
            f"no touch has role {missing[0]!r} ({construction.words[missing[0]]}): add it",
            loc=("touches",),
        )
    where = {r: index.index(i) for r, i in seen.items()}
    return np.array([points[where[r]] for r in construction.roles], dtype=np.float64)


def _touch_loc(touch_of: Mapping[str, int] | None, role: str) -> tuple[str | int, ...]:
    """The loc of the touch with `role` (its index in the body), or of the touches."""
    return ("touches",) if touch_of is None else ("touches", touch_of[role])


def check_geometry(
    construction: Construction, p: FloatArray, touch_of: Mapping[str, int] | None = None
) -> None:
    """Refuse coincident or collinear role points, naming the touch to move (its loc when
    `touch_of` gives each role's touch index)."""
    by_role = dict(zip(construction.roles, p, strict=True))
    start, x, plane = (
        by_role[construction.axis_from],
        by_role[construction.x_role],
        by_role[construction.plane_role],
    )
    length = float(np.linalg.norm(x - start))
    if length < MIN_SEPARATION_MM:
        raise InvalidInput(
            "collinear-points",
            f"the {construction.x_role!r} touch is {length:.3f} mm from the "
            f"{construction.axis_from!r} touch: they are one point and give no X axis; touch "
            f"{construction.words[construction.x_role]} well away from it",
            loc=_touch_loc(touch_of, construction.x_role),
        )
    ex = (x - start) / length
    off_axis = float(np.linalg.norm(np.cross(ex, plane - start)))
    if off_axis < MIN_SEPARATION_MM:
        raise InvalidInput(
            "collinear-points",
            f"the {construction.plane_role!r} touch is {off_axis:.3f} mm from the X axis: the "
            f"three points are on one line and give no plane; touch "
            f"{construction.words[construction.plane_role]}, away from the X axis",
            loc=_touch_loc(touch_of, construction.plane_role),
        )


def jacobian(build: Build, p: FloatArray) -> FloatArray:
    """d[origin, theta]/d[points] (6, 3N) of a construction at the points p (N, 3)."""
    R0, _ = build(p)
    flat = p.ravel()
    J = np.empty((6, flat.size))
    for k in range(flat.size):
        hi, lo = flat.copy(), flat.copy()
        hi[k] += JACOBIAN_STEP_MM
        lo[k] -= JACOBIAN_STEP_MM
        (R_hi, o_hi), (R_lo, o_lo) = build(hi.reshape(p.shape)), build(lo.reshape(p.shape))
        J[:3, k] = (o_hi - o_lo) / (2 * JACOBIAN_STEP_MM)
        J[3:, k] = (_small_angle(R0, R_hi) - _small_angle(R0, R_lo)) / (2 * JACOBIAN_STEP_MM)
    return J


def _small_angle(R0: FloatArray, R1: FloatArray) -> FloatArray:
    """theta with R1 = R0 exp([theta]x) for a rotation as small as a Jacobian step's (1e-7
    rad): the skew part of R0^T R1, exact to O(theta^3)."""
    D = R0.T @ R1
    return 0.5 * np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])


def distance_for_angle_mm(touch_noise_mm: float, max_angle_sigma_deg: float) -> float:
    """How far a touch must be from the one it sets a direction from (the x touch from the
    origin, the xy touch from the X axis) for that direction's angle 1-sigma to stay within
    `max_angle_sigma_deg`: two touches made in one orientation, each with `touch_noise_mm` per
    axis, differ by sqrt(2) x the noise across the line between them (the pointer's TCP
    error, common to both, moves them together), and the angle is that over the distance:
    the distance check_angle_sigma's refusal asks for, told before the touch."""
    return math.sqrt(2.0) * touch_noise_mm / math.radians(max_angle_sigma_deg)


def check_angle_sigma(
    construction: Construction,
    p: FloatArray,
    angle_sigma_deg: FloatArray,
    limit_deg: float,
    touch_of: Mapping[str, int] | None = None,
) -> None:
    """Refuse a set whose predicted angle 1-sigma exceeds `limit_deg`, saying how far the
    touch that sets it must be. The error scales as 1/distance (METHODS.md 7)."""
    by_role = dict(zip(construction.roles, p, strict=True))
    start, x = by_role[construction.axis_from], by_role[construction.x_role]
    plane = by_role[construction.plane_role]
    length = float(np.linalg.norm(x - start))
    off_axis = float(np.linalg.norm(np.cross((x - start) / length, plane - start)))
    about_x, about_y, about_z = (float(a) for a in angle_sigma_deg)
    x_sigma = max(about_y, about_z)
    if x_sigma > limit_deg:
        need = length * x_sigma / limit_deg
        raise InvalidInput(
            "insufficient-spread",
            f"the X axis is uncertain by {x_sigma:.3f} deg (1-sigma; at most {limit_deg:g}): the "
            f"{construction.x_role!r} touch is {length:.1f} mm from the {construction.axis_from!r} "
            f"touch; touch {construction.words[construction.x_role]} at least "
            f"{math.ceil(need)} mm from it",
            loc=_touch_loc(touch_of, construction.x_role),
            context={"angle_sigma_deg": x_sigma, "distance_mm": length, "needed_mm": need},
        )
    if about_x > limit_deg:
        need = off_axis * about_x / limit_deg
        raise InvalidInput(
            "insufficient-spread",
            f"the rotation about X is uncertain by {about_x:.3f} deg (1-sigma; at most "
            f"{limit_deg:g}): the {construction.plane_role!r} touch is {off_axis:.1f} mm from the "
            f"X axis; touch {construction.words[construction.plane_role]} at least "
            f"{math.ceil(need)} mm from the X axis",
            loc=_touch_loc(touch_of, construction.plane_role),
            context={"angle_sigma_deg": about_x, "distance_mm": off_axis, "needed_mm": need},
        )


def construct(
    construction: Construction,
    roles: Sequence[str],
    points_mm: FloatArray,
    point_covariance_mm2: FloatArray,
    *,
    touch_noise_mm: float,
    max_angle_sigma_deg: float = MAX_ANGLE_SIGMA_DEG,
    touch_index: Sequence[int] | None = None,
) -> FrameEstimate:
    """The frame of a construction from role touches: points (N, 3) mm in the base frame in
    touch order, their (3N, 3N) covariance in the same order; `touch_index` the body index
    of each touch, for the refusals' loc (default: 0..N-1)."""
    p = ordered_points(construction, roles, points_mm, touch_index)
    order = [list(roles).index(r) for r in construction.roles]
    body = list(range(len(roles))) if touch_index is None else list(touch_index)
    touch_of = {role: body[k] for role, k in zip(construction.roles, order, strict=True)}
    check_geometry(construction, p, touch_of)
    R, origin = construction.build(p)
    index = np.array([[3 * i + a for a in range(3)] for i in order]).ravel()
    C = point_covariance_mm2[np.ix_(index, index)]
    J = jacobian(construction.build, p)
    cov = J @ C @ J.T
    cov = 0.5 * (cov + cov.T)
    sigma_deg = np.degrees(np.sqrt(np.clip(np.diag(cov)[3:], 0.0, None)))
    check_angle_sigma(construction, p, sigma_deg, max_angle_sigma_deg, touch_of)
    nominal = (points_mm - origin) @ R
    return FrameEstimate(
        rotation=R,
        origin_mm=origin,
        covariance=cov,
        points_mm=np.asarray(points_mm, dtype=np.float64),
        nominal_mm=nominal,
        # an exact construction passes through what its roles define: no residual to show
        residuals_mm=np.zeros(len(roles)),
        used=np.ones(len(roles), dtype=bool),
        touch_noise_mm=touch_noise_mm,
        sigma_source="configured",
        dof=None,
    )
