"""DH / modified-DH forward kinematics, presets against vendor data, and the kinematics spec."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.kinematics.dh import DHLink, Kinematics, flange_pose, flange_poses, kinematics_from_spec
from app.vendors.registry import PRESETS

HALF_PI = math.pi / 2


# --- independent chains from the vendors' URDF numbers ------------------------------------------
# A URDF joint is a fixed origin (xyz, rpy with R = Rz(yaw) Ry(pitch) Rx(roll), i.e. scipy's
# extrinsic "xyz") followed by a rotation about the joint axis (all z here).
Origin = tuple[tuple[float, float, float], tuple[float, float, float]]


def _transform(xyz_m: tuple[float, float, float], rpy: tuple[float, float, float]) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    t[:3, 3] = np.asarray(xyz_m) * 1000.0
    return t


def _urdf_chain(origins: list[Origin], tail: list[Origin], q_rad: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    for (xyz, rpy), qi in zip(origins, q_rad, strict=True):
        joint = np.eye(4)
        joint[:3, :3] = Rotation.from_rotvec([0.0, 0.0, qi]).as_matrix()
        t = t @ _transform(xyz, rpy) @ joint
    for xyz, rpy in tail:
        t = t @ _transform(xyz, rpy)
    return t


def _ur_origins(kin: dict[str, tuple[float, ...]]) -> list[Origin]:
    names = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
    return [((kin[n][0], kin[n][1], kin[n][2]), (kin[n][3], kin[n][4], kin[n][5])) for n in names]


# ros-industrial/universal_robot ur_description/config/<model>/default_kinematics.yaml
# (x, y, z [m], roll, pitch, yaw [rad]), copied as published (the tiny z of the wrists and
# the 9-digit roll values included). These are the joint origins relative to
# base_link_inertia, which equals the controller's "base" frame (both are base_link turned
# by pi about Z: ur_description/urdf/ur_macro.xacro).
UR_DEFAULT_KINEMATICS: dict[str, dict[str, tuple[float, ...]]] = {
    "ur3e": {
        "shoulder": (0, 0, 0.15185, 0, 0, 0),
        "upper_arm": (0, 0, 0, 1.570796327, 0, 0),
        "forearm": (-0.24355, 0, 0, 0, 0, 0),
        "wrist_1": (-0.2132, 0, 0.13105, 0, 0, 0),
        "wrist_2": (0, -0.08535, -1.750557762378351e-11, 1.570796327, 0, 0),
        "wrist_3": (0, 0.0921, -1.8890025766262e-11, 1.570796326589793, math.pi, math.pi),
    },
    "ur5e": {
        "shoulder": (0, 0, 0.1625, 0, 0, 0),
        "upper_arm": (0, 0, 0, 1.570796327, 0, 0),
        "forearm": (-0.425, 0, 0, 0, 0, 0),
        "wrist_1": (-0.3922, 0, 0.1333, 0, 0, 0),
        "wrist_2": (0, -0.0997, -2.044881182297852e-11, 1.570796327, 0, 0),
        "wrist_3": (
            0,
            0.09959999999999999,
            -2.042830148012698e-11,
            1.570796326589793,
            math.pi,
            math.pi,
        ),
    },
    # ur10e: the stored ros-industrial/universal_robot copy has no
    # ur_description/config/ur10e/default_kinematics.yaml; these are the same fields of
    # ros-industrial/universal_robot ur_e_description/config/ur10e_default.yaml (commit
    # deca80cb0f5579a2a8519fc8a4d52f4f1aed586c, "hash: calib_5119701370761913513"), the
    # file default_kinematics.yaml was later copied from (same layout and units).
    "ur10e": {
        "shoulder": (0, 0, 0.1807, 0, 0, 0),
        "upper_arm": (0, 0, 0, 1.570796327, 0, 0),
        "forearm": (-0.6127, 0, 0, 0, 0, 0),
        "wrist_1": (-0.57155, 0, 0.17415, 0, 0, 0),
        "wrist_2": (0, -0.11985, -2.458164590756244e-11, 1.570796327, 0, 0),
        "wrist_3": (0, 0.11655, -2.390480459346185e-11, 1.570796326589793, math.pi, math.pi),
    },
    "ur16e": {
        "shoulder": (0, 0, 0.1807, 0, 0, 0),
        "upper_arm": (0, 0, 0, 1.570796327, 0, 0),
        "forearm": (-0.4784, 0, 0, 0, 0, 0),
        "wrist_1": (-0.36, 0, 0.17415, 0, 0, 0),
        "wrist_2": (0, -0.11985, -2.458164590756244e-11, 1.570796327, 0, 0),
        "wrist_3": (0, 0.11655, -2.390480459346185e-11, 1.570796326589793, math.pi, math.pi),
    },
}
# ur_macro.xacro: wrist_3_link -> flange rpy (0, -pi/2, -pi/2); flange -> tool0
# rpy (pi/2, 0, pi/2). tool0 is the controller's tool flange frame (all-zero TCP).
UR_TOOL0: list[Origin] = [((0, 0, 0), (0, -HALF_PI, -HALF_PI)), ((0, 0, 0), (HALF_PI, 0, HALF_PI))]


def _random_joints(seed: int, n: int = 50) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-180.0, 180.0, size=(n, 6))


@pytest.mark.parametrize("model", sorted(UR_DEFAULT_KINEMATICS))
def test_ur_presets_match_urdf_chain(model: str) -> None:
    """UR presets (DH from UR's DH article) equal the chain built from ur_description's
    default_kinematics.yaml + tool0, for 50 random joint sets, within 1e-6 mm."""
    origins = _ur_origins(UR_DEFAULT_KINEMATICS[model])
    q = _random_joints(1)
    rotations, positions = flange_poses(PRESETS[model], q)
    for i in range(len(q)):
        t = _urdf_chain(origins, UR_TOOL0, np.radians(q[i]))
        assert_allclose(positions[i], t[:3, 3], atol=1e-6)
        assert_allclose(rotations[i], t[:3, :3], atol=1e-9)


# tm5_900 and yaskawa_gp12 against their makers' URDF files: tests/kinematics/test_presets_urdf.py.


# UR's DH article (universal-robots.com, "DH parameters for calculations of kinematics and
# dynamics"): d1, a2, a3, d4, d5, d6 in m. At all-zero joints the arm lies along -X:
# flange at (a2 + a3, -(d4 + d6), d1 - d5), tool Z along -Y (R = Rx(90 deg)).
UR_DH_ARTICLE = {
    "ur3e": (0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921),
    "ur5e": (0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996),
    "ur10e": (0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655),
    "ur16e": (0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655),
}


@pytest.mark.parametrize("model", sorted(UR_DH_ARTICLE))
def test_ur_home_pose(model: str) -> None:
    """All-zero joints reproduce the home pose implied by UR's published DH table."""
    d1, a2, a3, d4, d5, d6 = (1000.0 * v for v in UR_DH_ARTICLE[model])
    rotation, position = flange_pose(PRESETS[model], np.zeros(6))
    assert_allclose(position, [a2 + a3, -(d4 + d6), d1 - d5], atol=1e-9)
    assert_allclose(rotation, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)


def test_ur5e_home_pose_numbers() -> None:
    """UR5e at all-zero joints: p[-0.8172, -0.2329, 0.0628, 1.5708, 0, 0] (m, rad)."""
    rotation, position = flange_pose(PRESETS["ur5e"], [0, 0, 0, 0, 0, 0])
    assert_allclose(position, [-817.2, -232.9, 62.8], atol=1e-9)
    assert_allclose(Rotation.from_matrix(rotation).as_rotvec(), [HALF_PI, 0, 0], atol=1e-12)


def test_tm5_900_home_pose() -> None:
    """TM5-900 at all-zero joints stands upright: flange 145.2 + 429 + 411.5 + 106 mm high,
    offset -(122.3 + 113.15) mm in Y (sums of the URDF offsets), tool Z along -Y."""
    rotation, position = flange_pose(PRESETS["tm5_900"], np.zeros(6))
    assert_allclose(position, [0.0, -235.45, 1091.7], atol=1e-9)
    assert_allclose(rotation @ [0, 0, 1], [0, -1, 0], atol=1e-12)


# --- conventions against closed forms ----------------------------------------------------------


def test_classic_dh_planar_arm() -> None:
    """Classic DH planar 3R (a = 300, 200, 100): p = sum a_i cos/sin(theta_1 + .. + theta_i)."""
    k = Kinematics("dh", (DHLink(300, 0, 0, 0), DHLink(200, 0, 0, 10), DHLink(100, 0, 0, 0)))
    q = np.array([20.0, -50.0, 75.0])
    cum = np.radians(np.cumsum(q + np.array([0.0, 10.0, 0.0])))
    expected = [
        sum(a * math.cos(t) for a, t in zip((300, 200, 100), cum, strict=True)),
        sum(a * math.sin(t) for a, t in zip((300, 200, 100), cum, strict=True)),
        0.0,
    ]
    rotation, position = flange_pose(k, q)
    assert_allclose(position, expected, atol=1e-9)
    assert_allclose(rotation, Rotation.from_rotvec([0, 0, cum[-1]]).as_matrix(), atol=1e-12)


def test_modified_dh_uses_previous_link_length() -> None:
    """Modified DH (Craig): row i carries a_{i-1}, alpha_{i-1}; a 3R planar arm with rows
    a = 0, 300, 200 ends at the third joint: p = 300 c1 + 200 c12, plus d along the last Z."""
    k = Kinematics("mdh", (DHLink(0, 0, 0, 0), DHLink(300, 0, 0, 0), DHLink(200, 0, 50, 0)))
    q = np.array([30.0, 45.0, -10.0])
    t1, t12 = math.radians(30), math.radians(75)
    rotation, position = flange_pose(k, q)
    assert_allclose(
        position,
        [300 * math.cos(t1) + 200 * math.cos(t12), 300 * math.sin(t1) + 200 * math.sin(t12), 50],
        atol=1e-9,
    )
    assert_allclose(
        rotation, Rotation.from_rotvec([0, 0, math.radians(65)]).as_matrix(), atol=1e-12
    )


def test_modified_dh_alpha_before_joint() -> None:
    """MDH alpha_{i-1} turns the joint axis before it rotates: Rx(90) then Rz(q)."""
    k = Kinematics("mdh", (DHLink(100, 90, 0, 0),))
    rotation, position = flange_pose(k, [30.0])
    assert_allclose(position, [100, 0, 0], atol=1e-12)
    expected = Rotation.from_rotvec([HALF_PI, 0, 0]) * Rotation.from_rotvec(
        [0, 0, math.radians(30)]
    )
    assert_allclose(rotation, expected.as_matrix(), atol=1e-12)


def test_flange_poses_vectorised_equals_single() -> None:
    q = _random_joints(3, 5)
    rotations, positions = flange_poses(PRESETS["ur10e"], q)
    for i in range(5):
        r, p = flange_pose(PRESETS["ur10e"], q[i])
        assert_allclose(rotations[i], r)
        assert_allclose(positions[i], p)


# --- kinematics spec ----------------------------------------------------------------------------


def test_spec_preset_and_links() -> None:
    assert kinematics_from_spec({"preset": "ur5e"}, presets=PRESETS) is PRESETS["ur5e"]
    spec = PRESETS["tm5_900"].to_spec()
    rebuilt = kinematics_from_spec(spec, presets=PRESETS)
    assert isinstance(rebuilt, Kinematics)
    assert rebuilt.links == PRESETS["tm5_900"].links
    assert rebuilt.convention == "dh"
    minimal = kinematics_from_spec(
        {"convention": "mdh", "links": [{"a": 0, "alpha": 0, "d": 1}]}, presets=PRESETS
    )
    assert isinstance(minimal, Kinematics)
    assert minimal.links[0].theta_offset_deg == 0.0
    # fields of the other variant left as None (a dumped union model) are ignored
    ur3e = kinematics_from_spec(
        {"preset": "ur3e", "convention": None, "links": None}, presets=PRESETS
    )
    assert isinstance(ur3e, Kinematics)
    assert ur3e.name == "ur3e"


@pytest.mark.parametrize(
    ("spec", "loc"),
    [
        ({"preset": "ur99"}, ("kinematics", "preset")),
        ({"preset": "ur5e", "links": []}, ("kinematics", "links")),
        (
            {"convention": "zyz", "links": [{"a": 0, "alpha": 0, "d": 0}]},
            ("kinematics", "convention"),
        ),
        ({"convention": "dh"}, ("kinematics", "links")),
        ({"convention": "dh", "links": []}, ("kinematics", "links")),
        ({"convention": "dh", "links": [{"a": 0, "d": 0}]}, ("kinematics", "links", 0, "alpha")),
        (
            {
                "convention": "dh",
                "links": [{"a": 0, "alpha": 0, "d": 0}, {"a": "x", "alpha": 0, "d": 0}],
            },
            ("kinematics", "links", 1, "a"),
        ),
        (
            {"convention": "dh", "links": [{"a": float("nan"), "alpha": 0, "d": 0}]},
            ("kinematics", "links", 0, "a"),
        ),
        (
            {"convention": "dh", "links": [{"a": 0, "alpha": 0, "d": 0, "theta": 1}]},
            ("kinematics", "links", 0, "theta"),
        ),
        ({"convention": "dh", "links": [5]}, ("kinematics", "links", 0)),
        ({"convention": "dh", "links": [], "extra": 1}, ("kinematics", "extra")),
    ],
)
def test_refuses_bad_kinematics_spec(spec: dict[str, Any], loc: tuple[str | int, ...]) -> None:
    """A bad kinematics spec -> invalid-options naming the field."""
    with pytest.raises(InvalidInput) as info:
        kinematics_from_spec(spec, presets=PRESETS)
    assert info.value.kind == "invalid-options"
    assert info.value.loc == loc, info.value


def test_refuses_non_finite_joints() -> None:
    with pytest.raises(InvalidInput) as info:
        flange_poses(PRESETS["ur5e"], [[0, 0, float("nan"), 0, 0, 0]])
    assert info.value.kind == "non-finite"


def test_presets_named_as_in_api() -> None:
    assert {"ur3e", "ur5e", "ur10e", "ur16e", "tm5_900", "yaskawa_gp12"} <= set(PRESETS)
    for name, k in PRESETS.items():
        assert k.name == name
        assert k.n_joints == 6
