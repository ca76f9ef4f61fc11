"""Pose formats of the API <-> rotation matrices and positions.

A pose is the flange in the robot base frame: ``base_from_flange`` as a rotation matrix
(3, 3) and a position (3,) in mm. Every conversion goes through
`scipy.spatial.transform.Rotation`; no Euler angle is turned into a matrix by hand.

| format | one pose | default units | rotation |
|---|---|---|---|
| matrix | 4x4 row-major (nested or flat 16) | mm | upper-left 3x3 |
| xyz_wxyz | x y z qw qx qy qz | mm | unit quaternion |
| xyz_xyzw | x y z qx qy qz qw (ROS) | mm | unit quaternion |
| kuka_abc | X Y Z A B C | mm, deg | Rz(A) Ry(B) Rx(C) |
| fanuc_wpr, yaskawa_rxyz, techman_rxyz | X Y Z W P R | mm, deg | Rz(R) Ry(P) Rx(W) |
| ur_rotvec | x y z rx ry rz | m, rad | rotation vector |
| joints | q1 .. qn | deg | forward kinematics |

`kuka_abc`'s A, B, C are intrinsic Z-Y'-X'' angles (scipy "ZYX"); `fanuc_wpr`'s W, P, R are
fixed-axis X, Y, Z angles (scipy "xyz"): both give the same matrix Rz Ry Rx, listed in
opposite order. Which maker's pendant shows which format is its declaration's
(`Maker.pose_format`, app/vendors/<maker>/), said beside each format by GET /v1/formats.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import SupportsFloat, TypeGuard, cast, get_args

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.kinematics.dh import Kinematics, flange_poses
from app.kinematics.urdf import UrdfChain
from app.solvers.validation import (
    check_finite,
    check_positions_mm,
    check_rotation_matrices,
    normalised_quaternions,
)
from app.words import Angle, Length, PoseFormat

#: The pose formats the API takes (app.words.PoseFormat); the tuple is read off the Literal,
#: so the schemas' enum and the parser cannot disagree.
POSE_FORMATS: tuple[PoseFormat, ...] = get_args(PoseFormat)
#: Formats that are X Y Z W P R with Rz(R) Ry(P) Rx(W) under another vendor's name.
WPR_FORMATS: tuple[PoseFormat, ...] = ("fanuc_wpr", "yaskawa_rxyz", "techman_rxyz")
#: Largest angle accepted in any angle field, degrees (ten turns). Bigger values are a
#: unit mistake or a sentinel, and their sine is numerically meaningless.
MAX_ABS_ANGLE_DEG = 3600.0
#: Tolerance on the last row of a 4x4 matrix being 0 0 0 1.
BOTTOM_ROW_ATOL = 1e-6

Loc = Sequence[str | int]

_MM_PER: dict[str, float] = {"mm": 1.0, "m": 1000.0}


@dataclass(frozen=True)
class PoseUnits:
    """PoseUnits of a pose's length values and angle values."""

    length: Length = "mm"
    angle: Angle = "deg"


_DEFAULT_UNITS: dict[str, PoseUnits] = {fmt: PoseUnits("mm", "deg") for fmt in POSE_FORMATS}
_DEFAULT_UNITS["ur_rotvec"] = PoseUnits("m", "rad")

# Component labels per format; arity = number of labels (joints: from the model).
_LABELS: dict[str, tuple[str, ...]] = {
    "matrix": tuple(f"m{r}{c}" for r in range(4) for c in range(4)),
    "xyz_wxyz": ("x", "y", "z", "qw", "qx", "qy", "qz"),
    "xyz_xyzw": ("x", "y", "z", "qx", "qy", "qz", "qw"),
    "kuka_abc": ("X", "Y", "Z", "A", "B", "C"),
    "fanuc_wpr": ("X", "Y", "Z", "W", "P", "R"),
    "yaskawa_rxyz": ("X", "Y", "Z", "Rx", "Ry", "Rz"),
    "techman_rxyz": ("X", "Y", "Z", "RX", "RY", "RZ"),
    "ur_rotvec": ("x", "y", "z", "rx", "ry", "rz"),
}


#: How each format's numbers make a rotation (what GET /v1/formats tells clients).
ROTATION_CONVENTIONS: dict[str, str] = {
    "matrix": "the upper-left 3x3 block of the 4x4 homogeneous matrix base_from_flange, "
    "row-major; last row 0 0 0 1",
    "xyz_wxyz": "unit quaternion, scalar first (w, x, y, z), as NDI's trackers write it",
    "xyz_xyzw": "unit quaternion, scalar last (x, y, z, w), as ROS writes it",
    "kuka_abc": "R = Rz(A) Ry(B) Rx(C): intrinsic Z-Y'-X'' Euler angles, A about Z first",
    "fanuc_wpr": "R = Rz(R) Ry(P) Rx(W): fixed-axis X-Y-Z angles, W about base X first "
    "(the same matrix as kuka_abc, angles listed in the opposite order)",
    "yaskawa_rxyz": "fixed-axis X-Y-Z angles Rx, Ry, Rz, as fanuc_wpr",
    "techman_rxyz": "fixed-axis X-Y-Z angles RX, RY, RZ, as fanuc_wpr",
    "ur_rotvec": "rotation vector (axis times angle): [x, y, z, rx, ry, rz], not a pendant's "
    "RPY view (send that as fanuc_wpr)",
    "joints": "joint angles through the robot's forward kinematics (the robot needs a model)",
}


def format_components(fmt: str) -> tuple[str, ...]:
    """The names of one pose's numbers in order; `joints` has one per joint (q1 .. qn)."""
    if _check_format(fmt) == "joints":
        return ("q1", "...", "qn")
    return _LABELS[fmt]


def _check_format(fmt: str) -> str:
    if fmt not in POSE_FORMATS:
        raise InvalidInput(
            "unknown-format",
            f"unknown pose format {fmt!r}; known formats: {', '.join(POSE_FORMATS)}",
            loc=("format",),
        )
    return fmt


def default_units(fmt: str) -> PoseUnits:
    """The units a format's values are in unless a `units` object overrides them."""
    return _DEFAULT_UNITS[_check_format(fmt)]


def resolve_units(fmt: str, override: Mapping[str, str] | None) -> PoseUnits:
    """The format's default units with the API `units` object's fields applied on top."""
    units = default_units(fmt)
    if override is None:
        return units
    if not isinstance(override, Mapping):
        raise InvalidInput(
            "invalid-options",
            "units must be an object such as {'length': 'mm', 'angle': 'deg'}",
            loc=("units",),
        )
    allowed: dict[str, tuple[str, ...]] = {"length": ("mm", "m"), "angle": ("deg", "rad")}
    for key, value in override.items():
        if key not in allowed:
            raise InvalidInput(
                "invalid-options",
                f"unknown units field {key!r}; expected 'length' and/or 'angle'",
                loc=("units", key),
            )
        if value not in allowed[key]:
            raise InvalidInput(
                "invalid-options",
                f"units.{key} must be one of {list(allowed[key])}, got {value!r}",
                loc=("units", key),
            )
    return PoseUnits(
        length=cast(Length, override.get("length", units.length)),
        angle=cast(Angle, override.get("angle", units.angle)),
    )


def _angle_given(units: PoseUnits | Mapping[str, str] | None) -> bool:
    """Whether the request's units name the angle unit (a resolved PoseUnits always does)."""
    return isinstance(units, PoseUnits) or (isinstance(units, Mapping) and "angle" in units)


def _as_units(fmt: str, units: PoseUnits | Mapping[str, str] | None) -> PoseUnits:
    if isinstance(units, PoseUnits):
        return units
    return resolve_units(fmt, units)


# --- named rotation converters (pure math, no validation) ---------------------------------


def matrix_from_kuka_abc(abc_deg: ArrayLike) -> FloatArray:
    """`kuka_abc` A, B, C in degrees ((3,) or (N, 3)) -> R = Rz(A) Ry(B) Rx(C), (3, 3) or
    (N, 3, 3)."""
    matrix: FloatArray = Rotation.from_euler("ZYX", abc_deg, degrees=True).as_matrix()
    return matrix


def kuka_abc_from_matrix(rotation: ArrayLike) -> FloatArray:
    """R ((3, 3) or (N, 3, 3)) -> `kuka_abc` A, B, C in degrees; at B = +-90 deg, C is 0."""
    with warnings.catch_warnings():
        # At gimbal lock only A - C (B = +90) or A + C (B = -90) is defined; scipy puts it
        # all in A and warns. The matrix round-trips either way.
        warnings.simplefilter("ignore", UserWarning)
        abc: FloatArray = Rotation.from_matrix(rotation).as_euler("ZYX", degrees=True)
    return abc


def matrix_from_fanuc_wpr(wpr_deg: ArrayLike) -> FloatArray:
    """`fanuc_wpr` W, P, R in degrees ((3,) or (N, 3)) -> R = Rz(R) Ry(P) Rx(W)."""
    matrix: FloatArray = Rotation.from_euler("xyz", wpr_deg, degrees=True).as_matrix()
    return matrix


def fanuc_wpr_from_matrix(rotation: ArrayLike) -> FloatArray:
    """R ((3, 3) or (N, 3, 3)) -> `fanuc_wpr` W, P, R in degrees; at P = +-90 deg, W is 0."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        wpr: FloatArray = Rotation.from_matrix(rotation).as_euler("xyz", degrees=True)
    return wpr


def matrix_from_rotvec(rotvec_rad: ArrayLike) -> FloatArray:
    """Rotation vector (axis * angle, rad; (3,) or (N, 3)) -> rotation matrix."""
    matrix: FloatArray = Rotation.from_rotvec(rotvec_rad).as_matrix()
    return matrix


def rotvec_from_matrix(rotation: ArrayLike) -> FloatArray:
    """Rotation matrix -> rotation vector in rad, angle in [0, pi] (as `ur_rotvec` has it)."""
    rotvec: FloatArray = Rotation.from_matrix(rotation).as_rotvec()
    return rotvec


def matrix_from_quaternion_wxyz(quaternion: ArrayLike) -> FloatArray:
    """Unit quaternion [w, x, y, z] ((4,) or (N, 4)) -> rotation matrix."""
    q = np.asarray(quaternion, dtype=np.float64)
    matrix: FloatArray = Rotation.from_quat(np.roll(q, -1, axis=-1)).as_matrix()
    return matrix


def quaternion_wxyz_from_matrix(rotation: ArrayLike) -> FloatArray:
    """Rotation matrix -> unit quaternion [w, x, y, z] with w >= 0."""
    xyzw = Rotation.from_matrix(rotation).as_quat(canonical=True)
    wxyz: FloatArray = np.roll(xyzw, 1, axis=-1)
    return wxyz


def matrix_from_quaternion_xyzw(quaternion: ArrayLike) -> FloatArray:
    """Unit quaternion [x, y, z, w] (ROS order) -> rotation matrix."""
    matrix: FloatArray = Rotation.from_quat(quaternion).as_matrix()
    return matrix


def quaternion_xyzw_from_matrix(rotation: ArrayLike) -> FloatArray:
    """Rotation matrix -> unit quaternion [x, y, z, w] with w >= 0."""
    xyzw: FloatArray = Rotation.from_matrix(rotation).as_quat(canonical=True)
    return xyzw


# --- parsing -----------------------------------------------------------------------------


def _is_number(value: object) -> TypeGuard[SupportsFloat]:
    return isinstance(value, int | float | np.floating | np.integer) and not isinstance(value, bool)


def _expected(fmt: str, labels: Sequence[str], units: PoseUnits) -> str:
    if fmt == "matrix":
        return "a 4x4 matrix (4 rows of 4 numbers, or 16 numbers row-major)"
    if fmt == "joints":
        return f"{len(labels)} joint angles in {units.angle}"
    return f"{len(labels)} numbers [{', '.join(labels)}]"


def _rows(fmt: str, poses: object, labels: Sequence[str], units: PoseUnits, loc: Loc) -> FloatArray:
    """The poses as an (N, arity) float array, or InvalidInput("invalid-pose") naming the pose."""
    if not isinstance(poses, Sequence) or isinstance(poses, str | bytes):
        raise InvalidInput(
            "invalid-pose", f"poses must be a list of poses in format {fmt!r}", loc=loc
        )
    arity = len(labels)
    if all(type(p) is list and len(p) == arity and all(type(v) is float for v in p) for p in poses):
        # Rows of floats, as a validated request holds them: one conversion, not one per value.
        return np.array(poses, dtype=np.float64).reshape(len(poses), arity)
    out = np.empty((len(poses), arity))
    for i, pose in enumerate(poses):
        flat = _flattened(fmt, i, pose, labels, units, loc)
        for j, value in enumerate(flat):
            if not _is_number(value):
                raise InvalidInput(
                    "invalid-pose",
                    f"pose {i + 1}: {labels[j]} must be a number, got {value!r}",
                    loc=(*loc, i, j),
                )
            out[i, j] = float(value)
    return out


def _flattened(
    fmt: str, i: int, pose: object, labels: Sequence[str], units: PoseUnits, loc: Loc
) -> Sequence[object]:
    """Pose i's values as one flat sequence of the format's arity (a matrix may come as rows)."""
    flat: object = pose
    if (
        fmt == "matrix"
        and isinstance(pose, Sequence)
        and len(pose) == 4
        and all(isinstance(r, Sequence) and not isinstance(r, str) for r in pose)
    ):
        if any(len(r) != 4 for r in pose):
            raise InvalidInput(
                "invalid-pose",
                f"pose {i + 1}: expected {_expected(fmt, labels, units)}, got rows of "
                f"lengths {[len(r) for r in pose]}",
                loc=(*loc, i),
            )
        flat = [v for r in pose for v in r]
    if not isinstance(flat, Sequence) or isinstance(flat, str | bytes):
        raise InvalidInput(
            "invalid-pose",
            f"pose {i + 1}: expected {_expected(fmt, labels, units)} for format {fmt!r}, "
            f"got {type(pose).__name__}",
            loc=(*loc, i),
        )
    if len(flat) != len(labels):
        raise InvalidInput(
            "invalid-pose",
            f"pose {i + 1}: expected {_expected(fmt, labels, units)} for format {fmt!r}, "
            f"got {len(flat)} values",
            loc=(*loc, i),
            context={"expected_arity": len(labels), "got_arity": len(flat)},
        )
    return flat


def _fields(fmt: str, arity: int) -> list[tuple[str, slice]]:
    """Field names of a format's values and where they sit in a row (for error locs)."""
    if fmt == "matrix":
        return [("matrix", slice(0, 16))]
    if fmt == "joints":
        return [("joints", slice(0, arity))]
    rotation_field = "quaternion" if fmt in ("xyz_wxyz", "xyz_xyzw") else "rotation"
    return [("position", slice(0, 3)), (rotation_field, slice(3, arity))]


def _check_values(fmt: str, values: FloatArray, labels: Sequence[str], loc: Loc) -> None:
    """Finite everywhere; angles within +-MAX_ABS_ANGLE_DEG (checked later in degrees)."""
    bad_rows = np.flatnonzero(~np.isfinite(values).all(axis=1))
    if bad_rows.size:
        i = int(bad_rows[0])
        for field, where in _fields(fmt, values.shape[1]):
            try:
                check_finite(values[i, where], loc=(*loc, i, field))
            except InvalidInput as err:
                j = where.start + int(err.loc[-1])
                raise InvalidInput(
                    "non-finite",
                    f"pose {i + 1}: {labels[j]} = {values[i, j]} is not a finite number",
                    loc=err.loc,
                ) from err


def _check_angles_deg(angles_deg: FloatArray, labels: Sequence[str], field: str, loc: Loc) -> None:
    too_big = np.abs(angles_deg) > MAX_ABS_ANGLE_DEG
    if too_big.any():
        i, j = (int(k) for k in np.argwhere(too_big)[0])
        raise InvalidInput(
            "out-of-range",
            f"pose {i + 1}: {labels[j]} = {angles_deg[i, j]:.6g} deg is beyond "
            f"+-{MAX_ABS_ANGLE_DEG:g} deg (wrong units, or a sentinel value)",
            loc=(*loc, i, field, j),
        )


def poses_from_format(
    fmt: str,
    poses: Sequence[object],
    *,
    units: PoseUnits | Mapping[str, str] | None = None,
    kinematics: Kinematics | UrdfChain | None = None,
    loc: Loc = ("poses",),
) -> tuple[FloatArray, FloatArray]:
    """Read N poses in format `fmt` -> (base_from_flange (N, 3, 3), flange positions (N, 3) mm).

    `units` (the API `units` object) overrides the format's default length and angle units.
    `kinematics` is needed for ``joints``. Bad input raises InvalidInput whose loc names the
    pose index and field, e.g. ("poses", 3, "quaternion").
    """
    _check_format(fmt)
    u = _as_units(fmt, units)
    if isinstance(kinematics, UrdfChain) and not _angle_given(units):
        u = PoseUnits(length=u.length, angle="rad")  # a URDF's joint values are radians
    loc = tuple(loc)
    labels = _labels(fmt, kinematics)
    values = _rows(fmt, poses, labels, u, loc)
    _check_values(fmt, values, labels, loc)
    mm = _MM_PER[u.length]
    to_deg = 1.0 if u.angle == "deg" else float(np.degrees(1.0))
    if fmt == "joints":
        assert kinematics is not None
        joints_deg = values * to_deg
        _check_angles_deg(joints_deg, labels, "joints", loc)
        if isinstance(kinematics, UrdfChain):
            return kinematics.flange_poses(np.radians(joints_deg), loc=loc)
        return flange_poses(kinematics, joints_deg, loc=loc)
    if fmt == "matrix":
        return _from_matrix_rows(values, mm, loc)
    positions = check_positions_mm(values[:, :3] * mm, loc=loc)
    return _rotations_from_rows(fmt, values, labels, to_deg, loc), positions


def _labels(fmt: str, kinematics: Kinematics | UrdfChain | None) -> tuple[str, ...]:
    """The names of a pose's values; for joints one per joint of the robot's model."""
    if fmt != "joints":
        return _LABELS[fmt]
    if kinematics is None:
        raise InvalidInput(
            "missing-kinematics",
            "the robot has no kinematics; set robot.kinematics (a preset such as ur5e, "
            "or DH links) to submit joint angles",
            loc=("kinematics",),
        )
    return tuple(f"q{k + 1}" for k in range(kinematics.n_joints))


def _from_matrix_rows(values: FloatArray, mm: float, loc: Loc) -> tuple[FloatArray, FloatArray]:
    """(R (N, 3, 3), positions (N, 3) mm) from rows of 16 values, each a 4x4 row-major."""
    n = values.shape[0]
    m = values.reshape(n, 4, 4)
    bottom_err = np.abs(m[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1, initial=0)
    bad = np.flatnonzero(bottom_err > BOTTOM_ROW_ATOL)
    if bad.size:
        i = int(bad[0])
        raise InvalidInput(
            "invalid-pose",
            f"pose {i + 1}: the last row of a 4x4 pose matrix must be [0, 0, 0, 1], got "
            f"{m[i, 3].tolist()}",
            loc=(*loc, i, "matrix"),
        )
    positions = check_positions_mm(m[:, :3, 3] * mm, loc=loc)
    rotations = check_rotation_matrices(m[:, :3, :3], loc=loc)
    return rotations.copy(), positions


def _rotations_from_rows(
    fmt: str, values: FloatArray, labels: Sequence[str], to_deg: float, loc: Loc
) -> FloatArray:
    """R (N, 3, 3) from the rotation part (values[:, 3:]) of a quaternion or angle format."""
    n = values.shape[0]
    if fmt in ("xyz_wxyz", "xyz_xyzw"):
        quats = normalised_quaternions(values[:, 3:7], loc=loc)
        if n == 0:
            return np.zeros((0, 3, 3))
        if fmt == "xyz_wxyz":
            return matrix_from_quaternion_wxyz(quats).reshape(n, 3, 3)
        return matrix_from_quaternion_xyzw(quats).reshape(n, 3, 3)
    angles_deg = values[:, 3:6] * to_deg
    _check_angles_deg(angles_deg, labels[3:], "rotation", loc)
    if n == 0:
        return np.zeros((0, 3, 3))
    if fmt == "kuka_abc":
        rotations = matrix_from_kuka_abc(angles_deg)
    elif fmt in WPR_FORMATS:
        rotations = matrix_from_fanuc_wpr(angles_deg)
    else:  # ur_rotvec
        rotations = matrix_from_rotvec(np.radians(angles_deg))
    return rotations.reshape(n, 3, 3)


@contextmanager
def one_pose(loc: Loc, number: int = 1) -> Iterator[None]:
    """Errors of reading a list of one pose, `[pose]` at `loc`, said of that one pose: its
    `loc` without the list's index 0 (the body holds one pose, not a list) and its sentence
    naming it `pose {number}` (a session's fifth touch is pose 5, not pose 1)."""
    try:
        yield
    except InvalidInput as exc:
        root = tuple(loc)
        if exc.loc[: len(root)] == root and exc.loc[len(root) : len(root) + 1] == (0,):
            exc.loc = (*root, *exc.loc[len(root) + 1 :])
        exc.detail = _FIRST_POSE.sub(f"pose {number}", exc.detail, count=1)
        exc.msg = _FIRST_POSE.sub(f"pose {number}", exc.msg, count=1)
        exc.args = (exc.detail,)
        raise


#: How the readers name the first pose of a list (`f"pose {i + 1}: ..."`).
_FIRST_POSE = re.compile(r"^pose 1\b")


def pose_from_format(
    fmt: str,
    pose: Sequence[object],
    *,
    units: PoseUnits | Mapping[str, str] | None = None,
    kinematics: Kinematics | None = None,
    loc: Loc = ("pose",),
) -> tuple[FloatArray, FloatArray]:
    """Read one pose -> (R (3, 3), position (3,) mm); errors locate it as (*loc, field)
    (`one_pose`)."""
    with one_pose(loc):
        rotations, positions = poses_from_format(
            fmt, [pose], units=units, kinematics=kinematics, loc=loc
        )
    return rotations[0], positions[0]


def pose_to_format(
    fmt: str,
    rotation: ArrayLike,
    position_mm: ArrayLike,
    *,
    units: PoseUnits | Mapping[str, str] | None = None,
) -> list[float] | list[list[float]]:
    """Write one pose (R (3, 3), position (3,) mm) in format `fmt` as plain floats.

    ``matrix`` gives a nested 4x4 list; quaternions come out with w >= 0; Euler angles in
    [-180, 180] with the middle angle in [-90, 90]; rotation vectors with angle in [0, pi].
    ``joints`` needs inverse kinematics and is refused ("unsupported").
    """
    _check_format(fmt)
    u = _as_units(fmt, units)
    if fmt == "joints":
        raise InvalidInput(
            "unsupported",
            "a pose cannot be written as joint angles: that needs inverse kinematics",
            loc=("format",),
        )
    r = check_rotation_matrices(np.asarray(rotation, dtype=np.float64)[None], loc=("pose",))[0]
    p = check_positions_mm(np.asarray(position_mm, dtype=np.float64).reshape(1, 3))[0]
    p_out = p / _MM_PER[u.length]
    from_deg = 1.0 if u.angle == "deg" else float(np.radians(1.0))

    if fmt == "matrix":
        m = np.eye(4)
        m[:3, :3] = r
        m[:3, 3] = p_out
        nested: list[list[float]] = [[float(v) for v in row] for row in m]
        return nested
    if fmt == "xyz_wxyz":
        rot: FloatArray = quaternion_wxyz_from_matrix(r)
    elif fmt == "xyz_xyzw":
        rot = quaternion_xyzw_from_matrix(r)
    elif fmt == "kuka_abc":
        rot = kuka_abc_from_matrix(r) * from_deg
    elif fmt in WPR_FORMATS:
        rot = fanuc_wpr_from_matrix(r) * from_deg
    else:  # ur_rotvec
        rot = np.degrees(rotvec_from_matrix(r)) * from_deg
    return [float(v) for v in np.concatenate([p_out, rot])]


# --- controller conventions <-> unit quaternion (the controller connectors' conversions) ---


def kuka_abc_from_quaternion_wxyz(quaternion: ArrayLike) -> FloatArray:
    """Unit quaternion [w, x, y, z] -> `kuka_abc` A, B, C in degrees (Rz(A) Ry(B) Rx(C))."""
    return kuka_abc_from_matrix(matrix_from_quaternion_wxyz(quaternion))


def quaternion_wxyz_from_kuka_abc(abc_deg: ArrayLike) -> FloatArray:
    """`kuka_abc` A, B, C in degrees -> unit quaternion [w, x, y, z] with w >= 0."""
    return quaternion_wxyz_from_matrix(matrix_from_kuka_abc(abc_deg))


def fanuc_wpr_from_quaternion_wxyz(quaternion: ArrayLike) -> FloatArray:
    """Unit quaternion [w, x, y, z] -> `fanuc_wpr` W, P, R in degrees (Rz(R) Ry(P) Rx(W))."""
    return fanuc_wpr_from_matrix(matrix_from_quaternion_wxyz(quaternion))


def quaternion_wxyz_from_fanuc_wpr(wpr_deg: ArrayLike) -> FloatArray:
    """`fanuc_wpr` W, P, R in degrees -> unit quaternion [w, x, y, z] with w >= 0."""
    return quaternion_wxyz_from_matrix(matrix_from_fanuc_wpr(wpr_deg))


def rotation_angle_deg(q_a: ArrayLike, q_b: ArrayLike) -> float:
    """The angle in degrees of the rotation between two unit quaternions [w, x, y, z]. Both
    made Rotations by one from_quat, not each from the matrix of its quaternion (every
    reconcile round compares each tool's frame this way)."""
    both = Rotation.from_quat(np.asarray([q_a, q_b], dtype=np.float64), scalar_first=True)
    return float(np.degrees((both[0].inv() * both[1]).magnitude()))
