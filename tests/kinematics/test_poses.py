"""Pose formats <-> (R, p): known values, gimbal lock, property round trips, refusals."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.kinematics.dh import kinematics_from_spec
from app.kinematics.poses import (
    POSE_FORMATS,
    PoseUnits,
    default_units,
    kuka_abc_from_matrix,
    matrix_from_fanuc_wpr,
    matrix_from_kuka_abc,
    one_pose,
    pose_from_format,
    pose_to_format,
    poses_from_format,
    resolve_units,
)
from app.kinematics.urdf import UrdfChain
from app.vendors.registry import PRESETS

FAST = settings(
    max_examples=150, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


# Independent truth: elementary rotations written out, not scipy's Euler sequences.
def rx(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


# --- known values --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "abc", [(0, 0, 0), (30, 0, 0), (0, 45, 0), (0, 0, -60), (10, 20, 30), (-170, 89, 5)]
)
def test_kuka_abc_is_rz_ry_rx(abc: tuple[float, float, float]) -> None:
    """KUKA A, B, C: R = Rz(A) Ry(B) Rx(C) (KSS FRAME convention), checked against matrices
    multiplied out from elementary rotations (an independent computation)."""
    a, b, c = abc
    rotations, positions = poses_from_format("kuka_abc", [[1.0, 2.0, 3.0, a, b, c]])
    assert_allclose(rotations[0], rz(a) @ ry(b) @ rx(c), atol=1e-12)
    assert_allclose(positions[0], [1.0, 2.0, 3.0])


@pytest.mark.parametrize("fmt", ["fanuc_wpr", "yaskawa_rxyz", "techman_rxyz"])
@pytest.mark.parametrize("wpr", [(90, 0, 0), (0, -30, 0), (0, 0, 45), (10, 20, 30)])
def test_wpr_is_rz_ry_rx(fmt: str, wpr: tuple[float, float, float]) -> None:
    """Fanuc W, P, R (and Yaskawa/Techman Rx, Ry, Rz): fixed-axis X then Y then Z,
    R = Rz(R) Ry(P) Rx(W), against elementary rotations (independent computation)."""
    w, p, r = wpr
    rotations, _ = poses_from_format(fmt, [[0, 0, 0, w, p, r]])
    assert_allclose(rotations[0], rz(r) @ ry(p) @ rx(w), atol=1e-12)


def test_kuka_and_fanuc_same_matrix_reversed_order() -> None:
    """KUKA (A, B, C) and Fanuc (W, P, R) = (C, B, A) describe the same rotation."""
    assert_allclose(matrix_from_kuka_abc([10, 20, 30]), matrix_from_fanuc_wpr([30, 20, 10]))


def test_abb_quaternion_from_rapid_manual() -> None:
    """RAPID reference manual, tooldata example 'gripper': quaternion [0.924, 0, 0.383, 0]
    is the tool's X and Z turned 45 deg about the wrist Y axis."""
    rotations, positions = poses_from_format(
        "xyz_wxyz", [[97.4, 0, 223.1, 0.924, 0, 0.383, 0]]
    )  # norm 1.00017: within 1e-3, normalised
    assert_allclose(rotations[0], ry(45), atol=1e-3)
    assert_allclose(positions[0], [97.4, 0, 223.1])


def test_ros_order_quaternion() -> None:
    """xyz_xyzw is ROS geometry_msgs order: [qx, qy, qz, qw]; 90 deg about Z."""
    h = math.sqrt(0.5)
    rotations, _ = poses_from_format("xyz_xyzw", [[0, 0, 0, 0, 0, h, h]])
    assert_allclose(rotations[0], rz(90), atol=1e-12)


def test_ur_rotvec_metres_radians() -> None:
    """UR p[x,y,z,rx,ry,rz]: metres and a rotation vector in rad (URScript manual 'pose');
    p[0.1, -0.2, 0.3, pi/2, 0, 0] is 90 deg about X at (100, -200, 300) mm."""
    rotations, positions = poses_from_format("ur_rotvec", [[0.1, -0.2, 0.3, math.pi / 2, 0, 0]])
    assert_allclose(rotations[0], rx(90), atol=1e-12)
    assert_allclose(positions[0], [100.0, -200.0, 300.0])


def test_matrix_nested_and_flat() -> None:
    """matrix: 4x4 row-major in mm, nested or flat 16 give the same pose."""
    m = np.eye(4)
    m[:3, :3] = rz(30) @ rx(10)
    m[:3, 3] = [10, 20, 30]
    r1, p1 = poses_from_format("matrix", [m.tolist()])
    r2, p2 = poses_from_format("matrix", [m.ravel().tolist()])
    assert_allclose(r1, r2)
    assert_allclose(p1, p2)
    assert_allclose(r1[0], m[:3, :3])
    assert_allclose(p1[0], [10, 20, 30])


def test_joints_use_forward_kinematics() -> None:
    """joints (deg) go through the robot's model: UR5e at all-zero joints."""
    rotations, positions = poses_from_format("joints", [[0] * 6], kinematics=PRESETS["ur5e"])
    assert_allclose(positions[0], [-817.2, -232.9, 62.8], atol=1e-9)
    assert_allclose(rotations[0], rx(90), atol=1e-12)


# --- units ---------------------------------------------------------------------------------


def test_default_units() -> None:
    assert default_units("ur_rotvec") == PoseUnits("m", "rad")
    assert default_units("kuka_abc") == PoseUnits("mm", "deg")
    assert resolve_units("ur_rotvec", {"angle": "deg"}) == PoseUnits("m", "deg")
    assert resolve_units("kuka_abc", None) == PoseUnits("mm", "deg")


def test_units_override_ur_pendant_in_degrees_and_mm() -> None:
    """A UR pendant set to show mm and degrees: the `units` object overrides m/rad."""
    r1, p1 = poses_from_format("ur_rotvec", [[0.1, 0.2, 0.3, math.pi / 2, 0, 0]])
    r2, p2 = poses_from_format(
        "ur_rotvec", [[100, 200, 300, 90, 0, 0]], units={"length": "mm", "angle": "deg"}
    )
    assert_allclose(r1, r2, atol=1e-12)
    assert_allclose(p1, p2)


def test_units_override_joints_in_radians() -> None:
    k = PRESETS["ur5e"]
    q = [10, -80, 45, 20, 90, 5]
    r1, p1 = poses_from_format("joints", [q], kinematics=k)
    r2, p2 = poses_from_format(
        "joints", [np.radians(q).tolist()], units={"angle": "rad"}, kinematics=k
    )
    assert_allclose(r1, r2, atol=1e-12)
    assert_allclose(p1, p2, atol=1e-9)


def test_pose_to_format_honours_units() -> None:
    out = pose_to_format("kuka_abc", rz(90), [1, 2, 3], units={"length": "m", "angle": "rad"})
    assert_allclose(out, [0.001, 0.002, 0.003, math.pi / 2, 0, 0], atol=1e-12)


# --- gimbal lock ---------------------------------------------------------------------------


@pytest.mark.parametrize("b", [90.0, -90.0, 90.0 - 1e-9, -90.0 + 1e-7, 89.9999])
def test_kuka_gimbal_lock_round_trip(b: float) -> None:
    """B = +-90 deg: A and C are not unique, but the matrix must come back the same."""
    pose = [5.0, 6.0, 7.0, 40.0, b, -25.0]
    r1, p1 = poses_from_format("kuka_abc", [pose])
    out = pose_to_format("kuka_abc", r1[0], p1[0])
    assert isinstance(out[0], float)
    r2, p2 = poses_from_format("kuka_abc", [out])
    assert_allclose(r2, r1, atol=1e-9)
    assert_allclose(p2, p1, atol=1e-9)
    assert_allclose(r1[0], rz(40) @ ry(b) @ rx(-25), atol=1e-12)


@pytest.mark.parametrize("fmt", ["fanuc_wpr", "yaskawa_rxyz", "techman_rxyz"])
@pytest.mark.parametrize("p", [90.0, -90.0, 90.0 - 1e-9, -89.99999])
def test_wpr_gimbal_lock_round_trip(fmt: str, p: float) -> None:
    """P = +-90 deg: W and R are not unique, the matrix is."""
    r1, p1 = poses_from_format(fmt, [[0, 0, 0, -35.0, p, 120.0]])
    r2, _ = poses_from_format(fmt, [pose_to_format(fmt, r1[0], p1[0])])
    assert_allclose(r2, r1, atol=1e-9)


def test_gimbal_lock_emits_no_warning() -> None:
    """scipy warns at gimbal lock; we expect it and keep it out of logs."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        kuka_abc_from_matrix(ry(90))


# --- property round trips --------------------------------------------------------------------

angles = st.floats(-180, 180, allow_nan=False)
near_lock = st.sampled_from([90.0, -90.0]).flatmap(
    lambda c: st.floats(c - 1e-3, c + 1e-3, allow_nan=False)
)
middle = st.one_of(st.floats(-90, 90, allow_nan=False), near_lock)
coords = st.floats(-2000, 2000, allow_nan=False)
EULER_FORMATS = ["kuka_abc", "fanuc_wpr", "yaskawa_rxyz", "techman_rxyz"]


def _assert_same_pose(fmt: str, first: list[float] | list[list[float]]) -> None:
    r1, p1 = pose_from_format(fmt, first)
    second = pose_to_format(fmt, r1, p1)
    r2, p2 = pose_from_format(fmt, second)
    assert_allclose(r2, r1, atol=1e-9)
    assert_allclose(p2, p1, atol=1e-9)


@pytest.mark.parametrize("fmt", EULER_FORMATS)
@FAST
@given(x=coords, y=coords, z=coords, a=angles, b=middle, c=angles)
def test_euler_format_round_trip(
    fmt: str, x: float, y: float, z: float, a: float, b: float, c: float
) -> None:
    """format -> (R, p) -> format -> (R, p) within 1e-9, including near gimbal lock."""
    _assert_same_pose(fmt, [x, y, z, a, b, c])


quaternions = st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4).filter(
    lambda q: np.linalg.norm(q) > 0.1
)


@pytest.mark.parametrize("fmt", ["xyz_wxyz", "xyz_xyzw"])
@FAST
@given(x=coords, y=coords, z=coords, q=quaternions)
def test_quaternion_format_round_trip(
    fmt: str, x: float, y: float, z: float, q: list[float]
) -> None:
    unit = (np.asarray(q) / np.linalg.norm(q)).tolist()
    _assert_same_pose(fmt, [x, y, z, *unit])


@FAST
@given(
    x=st.floats(-2, 2, allow_nan=False),
    y=st.floats(-2, 2, allow_nan=False),
    z=st.floats(-2, 2, allow_nan=False),
    v=st.lists(st.floats(-1, 1, allow_nan=False), min_size=3, max_size=3),
    angle=st.floats(0, math.pi, allow_nan=False),
)
def test_ur_rotvec_round_trip(x: float, y: float, z: float, v: list[float], angle: float) -> None:
    axis = np.asarray(v)
    if np.linalg.norm(axis) < 1e-3:
        axis = np.array([0.0, 0.0, 1.0])
    rotvec = axis / np.linalg.norm(axis) * angle
    _assert_same_pose("ur_rotvec", [x, y, z, *rotvec.tolist()])


@pytest.mark.parametrize("fmt", [f for f in POSE_FORMATS if f != "joints"])
@FAST
@given(seed=st.integers(0, 2**32 - 1), x=coords, y=coords, z=coords)
def test_matrix_to_format_and_back(fmt: str, seed: int, x: float, y: float, z: float) -> None:
    """(R, p) -> format -> (R, p) for random rotations (uniform on SO(3)), within 1e-9."""
    rotation = Rotation.random(random_state=seed).as_matrix()
    out = pose_to_format(fmt, rotation, [x, y, z])
    r2, p2 = pose_from_format(fmt, out)
    assert_allclose(r2, rotation, atol=1e-9)
    assert_allclose(p2, [x, y, z], atol=1e-9)


# --- refusals: one test per kind --------------------------------------------------------------


def _refused(kind: str, *args: Any, **kwargs: Any) -> InvalidInput:
    with pytest.raises(InvalidInput) as info:
        poses_from_format(*args, **kwargs)
    assert info.value.kind == kind, info.value
    return info.value


def test_refuses_wrong_arity() -> None:
    err = _refused("invalid-pose", "kuka_abc", [[0, 0, 0, 0, 0, 0], [1, 2, 3, 4, 5]])
    assert err.loc == ("poses", 1)  # the index stays 0-based; the sentence counts from 1
    assert "pose 2:" in err.detail
    assert "6 numbers" in err.detail
    assert "got 5" in err.detail


def test_refuses_joint_count_not_matching_model() -> None:
    err = _refused("invalid-pose", "joints", [[0] * 7], kinematics=PRESETS["ur5e"])
    assert "6 joint angles" in err.detail


def test_refuses_non_number() -> None:
    err = _refused("invalid-pose", "xyz_wxyz", [[0, 0, "1", 1, 0, 0, 0]])
    assert err.loc == ("poses", 0, 2)
    _refused("invalid-pose", "kuka_abc", [[0, 0, True, 0, 0, 0]])
    _refused("invalid-pose", "kuka_abc", "not a list")


def test_a_bare_number_as_a_pose_is_refused_naming_the_pose() -> None:
    # a pose that is neither a list nor a string (issue 51: `or` -> `and` let 5.0 on to len())
    err = _refused("invalid-pose", "kuka_abc", [[0] * 6, 5.0])
    assert err.loc == ("poses", 1)
    assert err.detail == (
        "pose 2: expected 6 numbers [X, Y, Z, A, B, C] for format 'kuka_abc', got float"
    )
    err = _refused("invalid-pose", "xyz_wxyz", [None])
    assert err.loc == ("poses", 0)
    assert err.detail.startswith("pose 1: expected 7 numbers [x, y, z, qw, qx, qy, qz]")
    assert err.detail.endswith("got NoneType")


def test_a_non_number_is_named_by_pose_number_and_label() -> None:
    err = _refused("invalid-pose", "kuka_abc", [[0] * 6, [0] * 6, [0, 0, "x", 0, 0, 0]])
    assert err.loc == ("poses", 2, 2)
    assert err.detail == "pose 3: Z must be a number, got 'x'"
    # joint labels count from 1, as the pendant does
    err = _refused("invalid-pose", "joints", [[0, "a", 0, 0, 0, 0]], kinematics=PRESETS["ur5e"])
    assert err.loc == ("poses", 0, 1)
    assert err.detail == "pose 1: q2 must be a number, got 'a'"


def test_a_bad_last_row_names_its_pose() -> None:
    m = np.eye(4)
    m[3, 0] = 0.5  # in column 0, not the pose's index: a mistake of axis shows
    err = _refused("invalid-pose", "matrix", [np.eye(4).tolist(), np.eye(4).tolist(), m.tolist()])
    assert err.loc == ("poses", 2, "matrix")
    assert err.detail.startswith("pose 3: the last row of a 4x4 pose matrix must be [0, 0, 0, 1]")


def test_one_pose_names_the_pose_by_its_number_and_drops_the_list_index() -> None:
    # a session's fifth touch read alone: loc without the list's 0, "pose 5" in every message
    with pytest.raises(InvalidInput) as info, one_pose(("body", "pose"), 5):
        poses_from_format("kuka_abc", [[0, 0, "x", 0, 0, 0]], loc=("body", "pose"))
    assert info.value.loc == ("body", "pose", 2)
    assert info.value.detail == "pose 5: Z must be a number, got 'x'"
    assert str(info.value) == info.value.detail  # what a log line or the CLI prints


def test_joints_of_a_urdf_robot_go_through_its_chain() -> None:
    text = (Path(__file__).resolve().parents[1] / "data" / "urdf" / "ur5e.urdf").read_text()
    chain = kinematics_from_spec(
        {"urdf": text, "base_link": "base", "tip_link": "tool0"}, presets=PRESETS
    )
    assert isinstance(chain, UrdfChain)
    q = np.radians([[10.0, -80.0, 70.0, -30.0, 90.0, 15.0], [0.0, -90.0, 90.0, 0.0, 45.0, 0.0]])
    rotations, positions = poses_from_format("joints", q.tolist(), kinematics=chain)
    R_chain, p_chain = chain.flange_poses(q)
    assert_allclose(rotations, R_chain, atol=1e-12)
    assert_allclose(positions, p_chain, atol=1e-9)


@pytest.mark.parametrize("fmt", ["xyz_wxyz", "xyz_xyzw"])
def test_quaternions_are_written_with_w_not_negative(fmt: str) -> None:
    # 270 deg about z is -90 deg: scipy's own quaternion of that matrix has w = -0.707
    pose = pose_to_format(fmt, rz(270.0), [0.0, 0.0, 0.0])
    assert isinstance(pose[0], float)
    w = pose[3] if fmt == "xyz_wxyz" else pose[6]
    assert w == pytest.approx(math.sqrt(0.5))


def test_refuses_non_finite() -> None:
    err = _refused("non-finite", "kuka_abc", [[0] * 6, [0, 0, 0, 0, float("nan"), 0]])
    assert err.loc == ("poses", 1, "rotation", 1)
    assert "B = nan" in err.detail
    err = _refused("non-finite", "xyz_wxyz", [[0, 0, 0, float("inf"), 0, 0, 0]])
    assert err.loc == ("poses", 0, "quaternion", 0)
    err = _refused("non-finite", "ur_rotvec", [[0, float("-inf"), 0, 0, 0, 0]])
    assert err.loc == ("poses", 0, "position", 1)


def test_refuses_tracker_sentinel() -> None:
    """A tracker that lost the tool reports about -3.7e28: out of range, never averaged."""
    err = _refused("out-of-range", "xyz_wxyz", [[0, 0, 0, 1, 0, 0, 0], [-3.7e28, 0, 0, 1, 0, 0, 0]])
    assert err.loc == ("poses", 1, "position")
    err = _refused("out-of-range", "kuka_abc", [[0, 0, 0, -3.7e28, 0, 0]])
    assert err.loc == ("poses", 0, "rotation", 0)


def test_refuses_metres_limit_after_unit_conversion() -> None:
    """101 m written in m is still beyond 100 m."""
    _refused("out-of-range", "ur_rotvec", [[101.0, 0, 0, 0, 0, 0]])


def test_refuses_non_orthonormal_matrix() -> None:
    m = np.eye(4)
    m[0, 0] = 1.01
    err = _refused("invalid-rotation", "matrix", [np.eye(4).tolist(), m.tolist()])
    assert err.loc == ("poses", 1, "rotation")


def test_refuses_reflection() -> None:
    m = np.diag([1.0, 1.0, -1.0, 1.0])
    err = _refused("invalid-rotation", "matrix", [m.tolist()])
    assert "det" in err.detail


def test_refuses_bad_last_row() -> None:
    m = np.eye(4)
    m[3, 0] = 1.0
    err = _refused("invalid-pose", "matrix", [m.tolist()])
    assert err.loc == ("poses", 0, "matrix")


def test_refuses_quaternion_norm() -> None:
    err = _refused(
        "invalid-rotation", "xyz_wxyz", [[0, 0, 0, 1, 0, 0, 0], [0, 0, 0, 1.01, 0, 0, 0]]
    )
    assert err.loc == ("poses", 1, "quaternion")


def test_normalises_nearly_unit_quaternion() -> None:
    rotations, _ = poses_from_format("xyz_wxyz", [[0, 0, 0, 1.0005, 0, 0, 0]])
    assert_allclose(rotations[0], np.eye(3), atol=1e-15)


def test_refuses_unknown_format() -> None:
    err = _refused("unknown-format", "euler_zyz", [[0] * 6])
    assert err.loc == ("format",)
    with pytest.raises(InvalidInput, match="unknown pose format"):
        pose_to_format("nope", np.eye(3), [0, 0, 0])


def test_refuses_joints_without_kinematics() -> None:
    err = _refused("missing-kinematics", "joints", [[0] * 6])
    assert "robot.kinematics" in err.detail


def test_refuses_bad_units() -> None:
    err = _refused("invalid-options", "kuka_abc", [[0] * 6], units={"length": "inch"})
    assert err.loc == ("units", "length")
    _refused("invalid-options", "kuka_abc", [[0] * 6], units={"speed": "fast"})


def test_pose_to_joints_is_unsupported() -> None:
    with pytest.raises(InvalidInput) as info:
        pose_to_format("joints", np.eye(3), [0, 0, 0])
    assert info.value.kind == "unsupported"


def test_empty_pose_list() -> None:
    rotations, positions = poses_from_format("kuka_abc", [])
    assert rotations.shape == (0, 3, 3)
    assert positions.shape == (0, 3)


# --- rows of floats (a validated request) are read in one conversion -----------------------

values = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False)


@FAST
@given(
    fmt=st.sampled_from([f for f in POSE_FORMATS if f not in ("matrix", "joints")]),
    rows=st.lists(st.lists(values, min_size=7, max_size=7), min_size=1, max_size=6),
    as_int=st.integers(min_value=0, max_value=6),
)
def test_rows_of_floats_read_as_rows_with_an_int_among_them(
    fmt: str, rows: list[list[float]], as_int: int
) -> None:
    """The one-conversion path (every value a float) and the value-by-value path (an int
    among them) read the same poses alike, or refuse them alike."""
    arity = 7 if fmt in ("xyz_wxyz", "xyz_xyzw") else 6
    floats = [r[:arity] for r in rows]
    if fmt in ("xyz_wxyz", "xyz_xyzw"):
        for r in floats:
            r[3] = abs(r[3]) + 0.5  # a quaternion well away from zero
    mixed = [list(r) for r in floats]
    mixed[0][as_int % arity] = int(mixed[0][as_int % arity])
    floats[0][as_int % arity] = float(mixed[0][as_int % arity])

    def read(poses: list[list[Any]]) -> Any:
        try:
            return poses_from_format(fmt, poses, units={"angle": "deg"})
        except InvalidInput as err:
            return (err.kind, err.loc)

    fast, slow = read(floats), read(mixed)
    if isinstance(fast, tuple) and isinstance(fast[0], str):
        assert fast == slow
    else:
        assert_allclose(fast[0], slow[0], rtol=0, atol=0)
        assert_allclose(fast[1], slow[1], rtol=0, atol=0)


def test_a_bool_or_a_string_among_floats_is_still_refused() -> None:
    for bad in (True, "1.0", None):
        err = _refused("invalid-pose", "xyz_wxyz", [[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, bad]])
        assert err.loc == ("poses", 0, 6)
