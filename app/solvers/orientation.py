"""Orientation of the tool frame relative to the flange.

Frames: a flange pose is (R, f), R the rotation flange -> base, f the flange position in mm
(base). The TCP is t (mm, flange frame); the tool orientation is Q, the rotation
tool frame -> flange frame, reported as a unit quaternion [w, x, y, z] with w >= 0.

Three procedures, one per method (which pendants teach each, and by what name, is each
maker's declaration, `Maker.teaches`; GET /v1/methods' descriptions name them):
- `orientation_from_translations` (tcp_z_x): pure translations of the flange along tool axes.
- `orientation_from_touches` (abc_2point): three touches of one fixed point.
- `orientation_from_world` (abc_world, 5D and 6D): tool axes aligned with base axes.

Uncertainty: each result carries `sigma_deg`, the 1-sigma of the small rotations about the
tool x, y and z axes (the error rotation Q_true^T Q_est as a rotation vector, in degrees),
obtained by propagating the given isotropic position noise linearly through the whole
solution (numerical Jacobian, `linear_sigma`). Without a noise figure there is nothing to
propagate and `sigma_source` is "none" (sigma reported as zeros, with a warning).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.quality import SigmaSource
from app.solvers.validation import check_finite, check_positions_mm, check_rotation_matrices
from app.words import WorkingAxis

#: A tool axis and the sign the TCP moved along it (a pure translation's `axis`).
AxisDirection = Literal["+z", "-z", "+x", "-x"]
#: Where an orientation's (or a laser result's) sigma came from (app.solvers.quality's
#: SigmaSource), or "none": no noise was given, so no sigma was estimated.
SigmaEstimate = Literal[SigmaSource, "none"]

#: Largest rotation allowed between the two poses of a pure translation, deg.
MAX_ORIENTATION_CHANGE_DEG = 0.5
#: Shortest accepted translation, mm: shorter moves turn position noise into large angles.
MIN_TRANSLATION_MM = 10.0
#: The X move must be at least this far (deg) from the Z line, else X and Z are "parallel".
MIN_X_Z_ANGLE_DEG = 30.0
#: An X move further than this (deg) from perpendicular to Z earns a warning.
WARN_ORTHOGONALITY_DEG = 2.0
#: Two moves along the same tool axis that disagree by more than this (deg) are refused.
MAX_SAME_AXIS_DISAGREEMENT_DEG = 30.0
#: Shortest lever (mm) between touch points in the 2-point method; shorter is degenerate.
MIN_LEVER_MM = 5.0
#: Levers shorter than this (mm) earn a warning: small touch errors become large angles.
WARN_LEVER_MM = 20.0

_UNIT = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class Direction:
    """A pure translation of the flange along one tool axis.

    `axis` names the tool axis and sign the TCP moved along (from -> to). Rotations are
    (3, 3) flange -> base, positions (3,) in mm (base frame).
    """

    axis: AxisDirection
    rotation_from: FloatArray
    position_from_mm: FloatArray
    rotation_to: FloatArray
    position_to_mm: FloatArray


@dataclass(frozen=True)
class OrientationResult:
    """A tool orientation with its quality figures.

    rotation: (3, 3) tool -> flange. quaternion_wxyz: the same, w >= 0.
    sigma_deg: 1-sigma of small rotations about tool x, y, z (deg); see `sigma_source`.
    residuals: per measurement, mm (translations: how far each move strays sideways from
    the fitted axis; touches and world alignment are exactly determined: zeros / empty).
    """

    rotation: FloatArray
    quaternion_wxyz: tuple[float, float, float, float]
    sigma_deg: tuple[float, float, float]
    residuals: tuple[float, ...]
    warnings: tuple[str, ...]
    sigma_source: SigmaEstimate = "none"


# --------------------------------------------------------------------------------------
# Shared helpers
# --------------------------------------------------------------------------------------


def quaternion_wxyz_from_matrix(rotation: ArrayLike) -> tuple[float, float, float, float]:
    """Unit quaternion [w, x, y, z] (w >= 0) of a (3, 3) rotation matrix."""
    q = Rotation.from_matrix(np.asarray(rotation, dtype=np.float64)).as_quat(
        canonical=True, scalar_first=True
    )
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def angle_between_deg(q1_wxyz: ArrayLike, q2_wxyz: ArrayLike) -> float:
    """Angle (deg, 0..180) of the rotation between two orientations given as [w, x, y, z]."""
    q1 = check_finite(q1_wxyz, loc=("q1",))
    q2 = check_finite(q2_wxyz, loc=("q2",))
    for name, q in (("q1", q1), ("q2", q2)):
        if q.shape != (4,) or not 0.5 < float(np.linalg.norm(q)) < 2.0:
            raise InvalidInput(
                "invalid-rotation",
                f"{name} must be a unit quaternion [w, x, y, z], got {q.tolist()}",
                loc=(name,),
            )
    r1 = Rotation.from_quat(q1, scalar_first=True)
    r2 = Rotation.from_quat(q2, scalar_first=True)
    return float(np.degrees((r1.inv() * r2).magnitude()))


#: rotation_error_deg takes the scipy way for rotations beyond 60 deg (cos below this).
SMALL_ROTATION_COS = 0.5


def rotation_error_deg(reference: ArrayLike, estimate: ArrayLike) -> FloatArray:
    """Small rotation (deg) about the reference tool axes taking `reference` to `estimate`.

    Both are (3, 3) tool -> flange; the result is the rotation vector of reference^T estimate.
    """
    ref = np.asarray(reference, dtype=np.float64)
    est = np.asarray(estimate, dtype=np.float64)
    m = ref.T @ est
    cos = 0.5 * (float(np.trace(m)) - 1.0)
    if cos < SMALL_ROTATION_COS:
        rotvec: FloatArray = Rotation.from_matrix(m).as_rotvec(degrees=True)
        return rotvec
    # Small rotation (the errors the sigmas' finite differences take): the log map from the
    # skew part, theta = atan2(|s|, cos), as accurate as the quaternion way and without the
    # rotation objects (most of a laser or 2-point solve's time).
    skew = 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    sin = float(np.linalg.norm(skew))
    scale = math.atan2(sin, cos) / sin if sin > 0.0 else 1.0
    out: FloatArray = np.degrees(scale * skew)
    return out


def linear_sigma(
    fn: Callable[[FloatArray], FloatArray],
    x0: FloatArray,
    sigma_in: FloatArray,
    *,
    step: float = 1e-3,
) -> FloatArray:
    """1-sigma of fn(x) for independent input errors sigma_in, by a central-difference Jacobian.

    fn maps the (n,) noisy inputs to (m,) outputs and must be smooth near x0 (all solvers
    here are: ratios, square roots and normalisations of well-conditioned quantities).
    """
    x0 = np.asarray(x0, dtype=np.float64)
    cols = []
    for j in range(x0.size):
        if sigma_in[j] == 0.0:
            continue
        e = np.zeros_like(x0)
        e[j] = step
        cols.append((fn(x0 + e) - fn(x0 - e)) / (2.0 * step) * sigma_in[j])
    if not cols:
        return np.zeros_like(fn(x0))
    jac = np.stack(cols, axis=1)
    out: FloatArray = np.sqrt(np.sum(jac**2, axis=1))
    return out


def _unit(v: FloatArray) -> FloatArray:
    out: FloatArray = v / np.linalg.norm(v)
    return out


def _orthogonalised(v: FloatArray, axis: FloatArray) -> FloatArray:
    """v with its component along the unit vector `axis` removed (not normalised)."""
    out: FloatArray = v - float(v @ axis) * axis
    return out


def _frame_from_z_x(z: FloatArray, x_hint: FloatArray) -> FloatArray:
    """Right-handed frame [X Y Z] with Z = z and X = x_hint made orthogonal to Z."""
    zu = _unit(z)
    xu = _unit(_orthogonalised(x_hint, zu))
    return np.column_stack([xu, np.cross(zu, xu), zu])


def _frame_from_x_y(x: FloatArray, y_hint: FloatArray) -> FloatArray:
    """Right-handed frame [X Y Z] with X = x and Y = y_hint made orthogonal to X."""
    xu = _unit(x)
    yu = _unit(_orthogonalised(y_hint, xu))
    return np.column_stack([xu, yu, np.cross(xu, yu)])


def _result(
    Q: FloatArray,
    sigma: FloatArray | None,
    residuals: Sequence[float],
    warnings: list[str],
    source: SigmaEstimate,
) -> OrientationResult:
    if sigma is None:
        sigma = np.zeros(3)
        warnings.append("no position noise given: the orientation's uncertainty was not estimated")
    return OrientationResult(
        rotation=Q,
        quaternion_wxyz=quaternion_wxyz_from_matrix(Q),
        sigma_deg=(float(sigma[0]), float(sigma[1]), float(sigma[2])),
        residuals=tuple(float(r) for r in residuals),
        warnings=tuple(warnings),
        sigma_source=source,
    )


def _check_noise(value: float | None, name: str) -> float | None:
    if value is None:
        return None
    v = float(check_finite(value, loc=("options", name)))
    if v < 0.0:
        raise InvalidInput(
            "invalid-options", f"{name} must be zero or positive, got {v:g}", loc=("options", name)
        )
    return v


def _checked_rotation(R: ArrayLike, loc: tuple[str | int, ...], what: str) -> FloatArray:
    try:
        arr = check_rotation_matrices(np.asarray(R, dtype=np.float64)[None], loc=loc)
    except InvalidInput as exc:
        detail = exc.detail.replace("pose 0", what)
        raise InvalidInput(exc.kind, detail, loc=loc) from None
    out: FloatArray = arr[0]
    return out


def _checked_position(p: ArrayLike, loc: tuple[str | int, ...], what: str) -> FloatArray:
    arr = np.asarray(p, dtype=np.float64)
    if arr.shape != (3,):
        raise InvalidInput("invalid-pose", f"{what}: a position needs 3 values (mm)", loc=loc)
    try:
        out = check_positions_mm(arr[None], loc=loc)
    except InvalidInput as exc:
        raise InvalidInput(exc.kind, exc.detail.replace("pose 0", what), loc=loc) from None
    pos: FloatArray = out[0]
    return pos


# --------------------------------------------------------------------------------------
# Pure translations (tcp_z_x)
# --------------------------------------------------------------------------------------


def _translation_axes(
    mid_rotations: Sequence[FloatArray],
    signs: FloatArray,
    moves: FloatArray,
) -> FloatArray:
    """Signed tool-axis unit vectors in the flange frame, one per move ((n, 3))."""
    out = np.empty_like(moves)
    for i, (R, s, d) in enumerate(zip(mid_rotations, signs, moves, strict=True)):
        out[i] = s * (R.T @ d) / np.linalg.norm(d)
    return out


def _combine(vectors: FloatArray, lengths: FloatArray) -> FloatArray:
    """Weighted mean direction: weights L^2 (a move's angular noise scales as 1/L)."""
    return _unit(np.sum(vectors * (lengths**2)[:, None], axis=0))


def _frame_from_moves(
    mid_rotations: Sequence[FloatArray],
    signs: FloatArray,
    is_z: NDArray[np.bool_],
    moves: FloatArray,
) -> FloatArray:
    axes = _translation_axes(mid_rotations, signs, moves)
    lengths = np.linalg.norm(moves, axis=1)
    z = _combine(axes[is_z], lengths[is_z])
    x_hint = _combine(axes[~is_z], lengths[~is_z]) if (~is_z).any() else np.array([1.0, 0, 0])
    return _frame_from_z_x(z, x_hint)


def orientation_from_translations(
    directions: Sequence[Direction], *, position_noise_mm: float | None = None
) -> OrientationResult:
    """Tool frame from pure flange translations along tool +-Z (required) and +-X (optional).

    Each move gives a tool axis in the flange frame: R^T (f_to - f_from) / |f_to - f_from|
    with the sign the direction names (R: the mean of the two poses' rotations). Several
    moves along one axis are averaged with weights L^2. X is made orthogonal to Z
    (Gram-Schmidt), Y = Z x X; without an X move, X is the flange X made orthogonal to Z.
    `position_noise_mm`: 1-sigma per coordinate of each recorded flange position.
    """
    noise = _check_noise(position_noise_mm, "position_noise_mm")
    if len(directions) == 0:
        raise InvalidInput(
            "invalid-direction",
            "no directions given: move the TCP along the tool's Z axis (at least one pair)",
            loc=("directions",),
        )
    moves = [_checked_move(i, d) for i, d in enumerate(directions)]
    mids = [m.rotation for m in moves]
    signs = np.array([1.0 if d.axis[0] == "+" else -1.0 for d in directions])
    is_z = np.array([d.axis[1] == "z" for d in directions], dtype=bool)
    if not is_z.any():
        raise InvalidInput(
            "invalid-direction",
            "no move along the tool's Z axis: the Z direction is required (X is optional)",
            loc=("directions",),
        )
    starts = np.array([m.start for m in moves])
    ends = np.array([m.end for m in moves])
    vectors = ends - starts
    axes = _translation_axes(mids, signs, vectors)
    lengths = np.linalg.norm(vectors, axis=1)
    _check_same_axis_agreement(directions, axes, is_z)
    z = _combine(axes[is_z], lengths[is_z])
    x = _combine(axes[~is_z], lengths[~is_z]) if (~is_z).any() else None
    warnings = _x_against_z(x, z, int(np.argmin(is_z)))
    Q = _frame_from_moves(mids, signs, is_z, vectors)
    # Sideways deviation of each move from the fitted axis, mm.
    fitted = np.where(is_z[:, None], Q[:, 2][None, :], Q[:, 0][None, :])
    residuals = [
        float(np.linalg.norm(_orthogonalised(lengths[i] * axes[i], fitted[i])))
        for i in range(len(directions))
    ]
    sigma = None
    if noise is not None:
        x0 = np.concatenate([starts.ravel(), ends.ravel()])
        n = len(directions)

        def fn(xv: FloatArray) -> FloatArray:
            mv = xv[3 * n :].reshape(n, 3) - xv[: 3 * n].reshape(n, 3)
            return rotation_error_deg(Q, _frame_from_moves(mids, signs, is_z, mv))

        sigma = linear_sigma(fn, x0, np.full(x0.size, noise))
    return _result(Q, sigma, residuals, warnings, "configured" if noise is not None else "none")


@dataclass(frozen=True)
class _Move:
    """One checked translation: flange positions (3,) mm and the mean rotation (3, 3)."""

    start: FloatArray
    end: FloatArray
    rotation: FloatArray


def _checked_move(i: int, d: Direction) -> _Move:
    """Direction i as a move, refused unless a long enough translation without rotation."""
    if d.axis not in ("+z", "-z", "+x", "-x"):
        raise InvalidInput(
            "invalid-direction",
            f"direction {i + 1}: axis must be one of +z, -z, +x, -x, got {d.axis!r}",
            loc=("directions", i, "axis"),
        )
    Ra = _checked_rotation(d.rotation_from, ("directions", i, "from"), f"direction {i + 1} 'from'")
    Rb = _checked_rotation(d.rotation_to, ("directions", i, "to"), f"direction {i + 1} 'to'")
    start = _checked_position(
        d.position_from_mm, ("directions", i, "from"), f"direction {i + 1} 'from'"
    )
    end = _checked_position(d.position_to_mm, ("directions", i, "to"), f"direction {i + 1} 'to'")
    pair = Rotation.from_matrix(np.stack([Ra, Rb]))
    change = float(np.degrees((pair[0].inv() * pair[1]).magnitude()))
    if change > MAX_ORIENTATION_CHANGE_DEG:
        raise InvalidInput(
            "orientation-changed",
            f"direction {i + 1} ({d.axis}): the flange orientation changed by {change:.2f} deg "
            f"between 'from' and 'to'; a pure translation keeps it within "
            f"{MAX_ORIENTATION_CHANGE_DEG} deg: jog in linear mode without rotating",
            loc=("directions", i, "to"),
            context={"change_deg": change},
        )
    length = float(np.linalg.norm(end - start))
    if length < MIN_TRANSLATION_MM:
        raise InvalidInput(
            "invalid-direction",
            f"direction {i + 1} ({d.axis}): the flange moved only {length:.2f} mm; move at "
            f"least {MIN_TRANSLATION_MM:g} mm along the tool axis",
            loc=("directions", i, "to"),
            context={"length_mm": length},
        )
    return _Move(start=start, end=end, rotation=pair.mean().as_matrix())


def _check_same_axis_agreement(
    directions: Sequence[Direction], axes: FloatArray, is_z: NDArray[np.bool_]
) -> None:
    """Refuse a move that points away from the first move along the same tool axis.

    Compared before averaging: two moves that contradict each other could cancel and leave
    no direction at all.
    """
    for i in range(len(directions)):
        first = int(np.flatnonzero(is_z == is_z[i])[0])
        off = float(np.degrees(np.arccos(np.clip(axes[i] @ axes[first], -1.0, 1.0))))
        if off > MAX_SAME_AXIS_DISAGREEMENT_DEG:
            raise InvalidInput(
                "invalid-direction",
                f"direction {i + 1} ({directions[i].axis}) points {off:.0f} deg away from "
                f"direction {first + 1} ({directions[first].axis}) along the same tool axis: check "
                "the sign and that the right axis was jogged",
                loc=("directions", i, "axis"),
            )


def _x_against_z(x: FloatArray | None, z: FloatArray, i_x: int) -> list[str]:
    """Refuse an X move (first at index i_x) nearly parallel to Z; warn when it is not
    perpendicular, or when there is none."""
    if x is None:
        return ["no X move: the tool X axis is the flange X axis made orthogonal to Z"]
    line_angle = float(np.degrees(np.arccos(min(1.0, abs(float(x @ z))))))
    if line_angle < MIN_X_Z_ANGLE_DEG:
        raise InvalidInput(
            "invalid-direction",
            f"the X move is only {line_angle:.1f} deg from the Z move: X and Z are (nearly) "
            "parallel; jog along the tool's X axis, perpendicular to Z",
            loc=("directions", i_x, "to"),
            context={"angle_deg": line_angle},
        )
    defect = 90.0 - float(np.degrees(np.arccos(float(np.clip(x @ z, -1.0, 1.0)))))
    if abs(defect) > WARN_ORTHOGONALITY_DEG:
        return [
            f"the X move is {abs(defect):.2f} deg from perpendicular to Z; X was made "
            "orthogonal to Z (check that the moves were pure tool-axis moves)"
        ]
    return []


# --------------------------------------------------------------------------------------
# Touches (abc_2point)
# --------------------------------------------------------------------------------------


def _frame_from_touch_points(
    t: FloatArray,
    rotations: FloatArray,
    positions: FloatArray,
    working_axis: WorkingAxis,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(Q, axis vector t - p2, y vector p3 - t) in the flange frame."""
    r = rotations[0] @ t + positions[0]
    p2 = rotations[1].T @ (r - positions[1])
    p3 = rotations[2].T @ (r - positions[2])
    w = t - p2
    y = p3 - t
    if working_axis == "x":
        Q = _frame_from_x_y(w, y)
    else:
        wu = _unit(w)
        yu = _unit(_orthogonalised(y, wu))
        Q = np.column_stack([np.cross(yu, wu), yu, wu])
    return Q, w, y


def orientation_from_touches(
    *,
    tcp_mm: ArrayLike,
    rotations: ArrayLike,
    positions_mm: ArrayLike,
    working_axis: WorkingAxis = "x",
    touch_noise_mm: float | None = None,
) -> OrientationResult:
    """Tool frame from three touches of one fixed point (abc_2point).

    rotations (3, 3, 3) and positions_mm (3, 3): the flange poses of
    0: the TCP touching the point (r = R0 t + f0);
    1: a point on the working axis behind the TCP (nearer the flange) touching r;
    2: a point in the plane of the working axis and tool +Y, on the +Y side, touching r
       (for working axis x, as the pendants of registry.X_AXIS_MAKERS take it: the tool
       XY plane).
    The working axis is (t - p2)/|t - p2|; Y comes from p3 - t made orthogonal to it.
    `touch_noise_mm`: 1-sigma per coordinate of each touch (flange position).
    The solution is exactly determined: the residuals are zeros.
    """
    if working_axis not in ("x", "z"):
        raise InvalidInput(
            "invalid-options",
            f"working_axis must be 'x' or 'z', got {working_axis!r}",
            loc=("options", "working_axis"),
        )
    noise = _check_noise(touch_noise_mm, "touch_noise_mm")
    t, R, f = _two_point_touches(tcp_mm, rotations, positions_mm)
    Q, w, y = _frame_from_touch_points(t, R, f, working_axis)
    warnings = _check_levers(w, y, working_axis)
    sigma = None
    if noise is not None:

        def fn(xv: FloatArray) -> FloatArray:
            Qp = _frame_from_touch_points(t, R, xv.reshape(3, 3), working_axis)[0]
            return rotation_error_deg(Q, Qp)

        sigma = linear_sigma(fn, f.ravel(), np.full(9, noise))
    return _result(
        Q, sigma, (0.0, 0.0, 0.0), warnings, "configured" if noise is not None else "none"
    )


def _two_point_touches(
    tcp_mm: ArrayLike, rotations: ArrayLike, positions_mm: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The TCP (3,) and the 2-point method's three touches, R (3, 3, 3) and f (3, 3), checked."""
    t = check_finite(tcp_mm, loc=("options", "tcp_mm"))
    if t.shape != (3,):
        raise InvalidInput(
            "invalid-options", "tcp_mm needs 3 values (mm)", loc=("options", "tcp_mm")
        )
    R = np.asarray(rotations, dtype=np.float64)
    f = np.asarray(positions_mm, dtype=np.float64)
    if R.shape[0] != 3 or f.shape[0] != 3:
        raise InvalidInput(
            "too-few-poses" if min(R.shape[0], f.shape[0]) < 3 else "invalid-pose",
            "the 2-point method takes exactly 3 touches: TCP, a point on the working axis "
            "behind it, a point on +Y",
            loc=("poses",),
        )
    return t, check_rotation_matrices(R, loc=("poses",)), check_positions_mm(f, loc=("poses",))


def _check_levers(w: FloatArray, y: FloatArray, working_axis: WorkingAxis) -> list[str]:
    """Refuse a working-axis or +Y lever shorter than MIN_LEVER_MM; warn below WARN_LEVER_MM."""
    lever_axis = float(np.linalg.norm(w))
    if lever_axis < MIN_LEVER_MM:
        raise InvalidInput(
            "degenerate-poses",
            f"touch 2 puts the working-axis point only {lever_axis:.2f} mm from the TCP: touch "
            f"the point with a spot on the {working_axis.upper()} axis at least "
            f"{MIN_LEVER_MM:g} mm behind the TCP",
            loc=("poses", 1),
            context={"lever_mm": lever_axis},
        )
    lever_y = float(np.linalg.norm(_orthogonalised(y, w / lever_axis)))
    if lever_y < MIN_LEVER_MM:
        raise InvalidInput(
            "degenerate-poses",
            f"the three touched tool points are (nearly) collinear: touch 3 is only "
            f"{lever_y:.2f} mm off the working axis; touch with a point on the tool's +Y "
            f"side at least {MIN_LEVER_MM:g} mm away from the axis",
            loc=("poses", 2),
            context={"lever_mm": lever_y},
        )
    return [
        f"the {name} lever is only {lever:.1f} mm: touch errors are magnified into "
        "orientation errors; use points further apart"
        for name, lever in (("working-axis", lever_axis), ("+Y", lever_y))
        if lever < WARN_LEVER_MM
    ]


# --------------------------------------------------------------------------------------
# World alignment (abc_world, 5D and 6D)
# --------------------------------------------------------------------------------------


def _parse_base_direction(value: object, key: str) -> FloatArray:
    text = str(value).strip().lower()
    if len(text) == 1:
        text = "+" + text
    if len(text) != 2 or text[0] not in "+-" or text[1] not in _UNIT:
        raise InvalidInput(
            "invalid-options",
            f"align.{key}: a base direction is one of +x, -x, +y, -y, +z, -z; got {value!r}",
            loc=("options", "align", key),
        )
    v = np.zeros(3)
    v[_UNIT[text[1]]] = 1.0 if text[0] == "+" else -1.0
    return v


def orientation_from_world(
    *,
    rotation: ArrayLike,
    align: Mapping[str, str],
    working_axis: WorkingAxis = "x",
) -> OrientationResult:
    """Tool frame from one flange pose with tool axes aligned to base axes (abc_world).

    rotation (3, 3): flange -> base at the aligned pose. align maps tool axes to base
    directions, e.g. {"x": "-z"} (5D) or {"x": "-z", "y": "+y"} (6D). Q = R^T M, M holding
    the named base directions. With one axis named (5D) only that axis is fixed and the
    rotation about it is the one closest to the flange frame (the smallest rotation from the
    flange frame that carries the flange's own axis onto the named direction).
    `working_axis` documents the 5D convention: a 5D alignment normally names it; naming
    another axis is accepted and earns a warning. No measurement redundancy: no residuals,
    and no noise model (sigma_source "none").
    """
    if working_axis not in ("x", "z"):
        raise InvalidInput(
            "invalid-options",
            f"working_axis must be 'x' or 'z', got {working_axis!r}",
            loc=("options", "working_axis"),
        )
    R = check_rotation_matrices(np.asarray(rotation, dtype=np.float64)[None], loc=("poses",))[0]
    named = _aligned_axes(align)
    warnings: list[str] = []
    if len(named) == 1:
        ((a, b_base),) = named.items()
        if a != _UNIT[working_axis]:
            warnings.append(
                f"5D alignment of tool {'xyz'[a]}, not of the working axis {working_axis}: "
                "the rotation about tool " + "xyz"[a] + " was taken as close to the flange as "
                "possible"
            )
        Q = _closest_alignment(a, R.T @ b_base, warnings)
    else:
        Q = R.T @ _aligned_frame(named)
    return _result(Q, np.zeros(3), (), warnings, "none")


def _aligned_axes(align: Mapping[str, str]) -> dict[int, FloatArray]:
    """Tool axis index -> the base direction (unit) it is aligned with, checked: one to three
    distinct tool axes onto perpendicular base directions."""
    if not isinstance(align, Mapping) or not 1 <= len(align) <= 3:
        raise InvalidInput(
            "invalid-options",
            "align must name one (5D) or two (6D) tool axes, e.g. {'x': '-z', 'y': '+y'}",
            loc=("options", "align"),
        )
    named: dict[int, FloatArray] = {}
    for key, value in align.items():
        k = str(key).strip().lower()
        if k not in _UNIT:
            raise InvalidInput(
                "invalid-options",
                f"align: {key!r} is not a tool axis; use x, y or z",
                loc=("options", "align", str(key)),
            )
        if _UNIT[k] in named:
            raise InvalidInput(
                "invalid-options",
                f"align names the tool axis {k} twice",
                loc=("options", "align", str(key)),
            )
        v = _parse_base_direction(value, k)
        for other, ov in named.items():
            if abs(float(v @ ov)) > 0.5:
                raise InvalidInput(
                    "invalid-options",
                    f"align maps tool {'xyz'[other]} and tool {k} onto the same base axis; "
                    "tool axes are perpendicular, so they must go to different base axes",
                    loc=("options", "align", str(key)),
                )
        named[_UNIT[k]] = v
    return named


def _closest_alignment(a: int, w: FloatArray, warnings: list[str]) -> FloatArray:
    """The smallest rotation from the flange frame carrying flange axis a onto w (unit, flange
    frame); the half-turn about a fixed perpendicular axis when w is opposite it."""
    e = np.zeros(3)
    e[a] = 1.0
    cross = np.cross(e, w)
    s = float(np.linalg.norm(cross))
    c = float(e @ w)
    if s >= 1e-12:
        turned: FloatArray = Rotation.from_rotvec(cross / s * float(np.arctan2(s, c))).as_matrix()
        return turned
    if c > 0:
        return np.eye(3)
    # Half-turn: every axis perpendicular to e is equally close; pick a fixed one.
    spin = np.zeros(3)
    spin[(a + 2) % 3] = 1.0
    warnings.append(
        "the named direction is opposite the flange's own axis: the half-turn "
        f"about the flange {'xyz'[(a + 2) % 3]} axis was chosen"
    )
    half_turn: FloatArray = Rotation.from_rotvec(np.pi * spin).as_matrix()
    return half_turn


def _aligned_frame(named: dict[int, FloatArray]) -> FloatArray:
    """M (3, 3) holding the named base directions as columns, the third one completing two
    to a right-handed frame; refuses three that are left-handed."""
    M = np.zeros((3, 3))
    for a, v in named.items():
        M[:, a] = v
    if len(named) == 2:
        missing = ({0, 1, 2} - set(named)).pop()
        i, j = (missing + 1) % 3, (missing + 2) % 3
        M[:, missing] = np.cross(M[:, i], M[:, j])
    elif np.linalg.det(M) < 0:
        raise InvalidInput(
            "invalid-options",
            "align names a left-handed set of axes (x cross y must equal z); name two "
            "axes and let the third follow",
            loc=("options", "align"),
        )
    return M
