"""Robots from URDF (app.kinematics.urdf): FK equal to the DH preset and to yourdfpy's own FK,
joint limits, and every kind of unusable URDF refused naming the problem."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.kinematics.dh import flange_poses, kinematics_from_spec
from app.kinematics.poses import poses_from_format
from app.kinematics.urdf import UrdfChain, chain_from_spec
from app.vendors.registry import PRESETS

DATA = Path(__file__).resolve().parents[1] / "data" / "urdf"
UR5E = (DATA / "ur5e.urdf").read_text()
IRB4600 = (DATA / "abb_irb4600_40_255.urdf").read_text()


def _chain(text: str, **fields: str) -> UrdfChain:
    chain = kinematics_from_spec({"urdf": text, **fields}, presets=PRESETS)
    assert isinstance(chain, UrdfChain)
    return chain


def _random_joints(chain: UrdfChain, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    movable = [j for j in chain.joints if j.kind != "fixed"]
    low = np.array([max(j.lower_rad or -np.pi, -np.pi) for j in movable])
    high = np.array([min(j.upper_rad or np.pi, np.pi) for j in movable])
    return rng.uniform(low, high, (n, len(movable)))


def test_ur5e_urdf_equals_the_dh_preset_to_1e6_mm() -> None:
    """UR's URDF (ur5e.urdf, from airo-models) from its `base` link (the controller's Base
    frame) to `tool0` (the all-zero tool flange) is the ur5e DH preset, over random joints."""
    chain = _chain(UR5E, base_link="base")
    assert chain.tip_link == "tool0"
    assert chain.joint_names == (
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    )
    q = _random_joints(chain, 500, seed=1)
    R_urdf, p_urdf = chain.flange_poses(q)
    R_dh, p_dh = flange_poses(PRESETS["ur5e"], np.degrees(q))
    assert np.abs(p_urdf - p_dh).max() < 1e-6
    assert np.abs(R_urdf - R_dh).max() < 1e-9


def test_ur5e_from_base_link_differs_by_the_stated_fixed_turn() -> None:
    """From the URDF's root `base_link` (REP-103: x forward) the same flange poses are turned
    by 180 deg about z: base_link -> base is the fixed joint rpy (0, 0, pi) of the URDF."""
    chain = _chain(UR5E)
    assert chain.base_link == "base_link"
    q = _random_joints(chain, 200, seed=2)
    R_urdf, p_urdf = chain.flange_poses(q)
    R_dh, p_dh = flange_poses(PRESETS["ur5e"], np.degrees(q))
    turn = Rotation.from_euler("z", 180.0, degrees=True)
    assert np.abs(p_urdf - turn.apply(p_dh)).max() < 1e-6
    assert np.abs(R_urdf - turn.as_matrix() @ R_dh).max() < 1e-9


@pytest.mark.parametrize("text", [UR5E, IRB4600], ids=["ur5e", "irb4600"])
def test_fk_equals_yourdfpys_own_scene_graph(text: str) -> None:
    """Our chain walk against the library's forward kinematics (its scene graph)."""
    chain = _chain(text)
    model = yourdfpy.URDF.load(io.BytesIO(text.encode()), load_meshes=False)
    for q in _random_joints(chain, 20, seed=3):
        model.update_cfg(dict(zip(chain.joint_names, q, strict=True)))
        expected = model.get_transform(chain.tip_link, chain.base_link)
        R, p = chain.flange_poses(q[None, :])
        assert_allclose(p[0], expected[:3, 3] * 1000.0, atol=1e-6)
        assert_allclose(R[0], expected[:3, :3], atol=1e-9)


def test_irb4600_home_pose_is_its_published_geometry() -> None:
    """All joints at zero: tool0 at x = 175 + 331 + 939 + 135 mm, z = 495 + 1095 + 175 mm
    (the IRB 4600-40/2.55's link lengths), tool z along base x (the flange faces forward)."""
    chain = _chain(IRB4600)
    assert chain.tip_link == "tool0"
    R, p = chain.flange_poses(np.zeros((1, 6)))
    assert_allclose(p[0], [1580.0, 0.0, 1765.0], atol=1e-6)
    assert_allclose(R[0][:, 2], [1.0, 0.0, 0.0], atol=1e-4)


def test_joint_values_are_radians_unless_units_say_degrees() -> None:
    chain = _chain(IRB4600)
    q = np.array([[0.3, -0.2, 0.4, 1.0, -0.5, 2.0]])
    R_rad, p_rad = poses_from_format("joints", q.tolist(), kinematics=chain)
    R_deg, p_deg = poses_from_format(
        "joints", np.degrees(q).tolist(), kinematics=chain, units={"angle": "deg"}
    )
    assert_allclose(p_rad, p_deg, atol=1e-9)
    assert_allclose(R_rad, R_deg, atol=1e-12)


def test_a_joint_outside_its_limits_is_refused_naming_it() -> None:
    chain = _chain(IRB4600)
    q = np.zeros((3, 6))
    q[2, 1] = np.radians(170.0)  # joint_2 goes -90 .. +150 deg
    with pytest.raises(InvalidInput) as caught:
        chain.flange_poses(q)
    assert caught.value.kind == "out-of-range"
    assert "joint 'joint_2' (q2)" in caught.value.detail
    assert "-90 .. 150 deg" in caught.value.detail
    assert caught.value.loc == ("poses", 2, "joints")


def _refused(spec: dict[str, str]) -> InvalidInput:
    with pytest.raises(InvalidInput) as caught:
        chain_from_spec(spec)
    assert caught.value.kind == "invalid-kinematics"
    return caught.value


def test_malformed_xml_is_refused_with_the_parsers_words() -> None:
    error = _refused({"urdf": IRB4600.replace("</robot>", "")})
    assert "not well-formed XML" in error.detail
    assert error.loc == ("kinematics", "urdf")
    assert "<robot>" in _refused({"urdf": "<sdf version='1.7'/>"}).detail
    laughs = '<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">]><robot name="&a;"/>'
    assert "DOCTYPE" in _refused({"urdf": laughs}).detail
    assert "not valid text" in _refused({"urdf": "<robot name='\ud800'/>"}).detail


def test_no_path_from_base_to_tip_is_refused() -> None:
    """A tip in another tree of the URDF (a second robot, a fixture) has no chain to the base."""
    text = IRB4600.replace(
        "</robot>",
        '<link name="table"/><link name="clamp"/><joint name="clamp_joint" type="fixed">'
        '<parent link="table"/><child link="clamp"/></joint></robot>',
    )
    error = _refused({"urdf": text, "base_link": "base_link", "tip_link": "clamp"})
    assert "no path from base_link 'base_link' to tip_link 'clamp'" in error.detail
    assert error.loc == ("kinematics", "tip_link")
    assert "name the robot's base as base_link" in _refused({"urdf": text}).detail
    missing = _refused({"urdf": IRB4600, "tip_link": "flange"})
    assert "no link 'flange'" in missing.detail


def test_a_moving_base_is_refused() -> None:
    error = _refused({"urdf": IRB4600, "base_link": "link_2"})
    assert "moves with joint 'joint_1'" in error.detail


def _with_joint(extra_link: str, joint: str) -> str:
    return IRB4600.replace("</robot>", f'<link name="{extra_link}"/>{joint}</robot>')


def test_mimic_joints_are_refused_naming_the_joint() -> None:
    text = IRB4600.replace(
        '<joint name="joint_6" type="revolute">',
        '<joint name="joint_6" type="revolute"><mimic joint="joint_5" multiplier="1"/>',
    )
    error = _refused({"urdf": text})
    assert "joint 'joint_6' mimics joint 'joint_5'" in error.detail


@pytest.mark.parametrize("kind", ["prismatic", "floating", "planar"])
def test_joints_it_cannot_handle_are_refused_naming_them(kind: str) -> None:
    limit = '<limit lower="0" upper="1" effort="1" velocity="1"/>' if kind == "prismatic" else ""
    text = _with_joint(
        "gun",
        f'<joint name="gun_axis" type="{kind}"><parent link="tool0"/><child link="gun"/>'
        f'<axis xyz="0 0 1"/>{limit}</joint>',
    )
    error = _refused({"urdf": text})
    assert f"joint 'gun_axis' is '{kind}'" in error.detail
    assert "supported joints are revolute, continuous and fixed" in error.detail


def test_continuous_joints_are_supported_without_limits() -> None:
    text = IRB4600.replace(
        '<joint name="joint_6" type="revolute">', '<joint name="joint_6" type="continuous">'
    )
    chain = _chain(text)
    q = np.zeros((2, 6))
    q[1, 5] = 20.0  # radians, beyond the revolute limit of 400 deg
    R, p = chain.flange_poses(q)
    # tool0 is joint_6's child with no offset: it turns about its own z (joint_6's axis) by
    # 20 rad, which is 20 - 6 pi = 1.150 rad, and stays where it was
    turn = Rotation.from_matrix(R[0].T @ R[1])
    assert_allclose(turn.as_rotvec(), [0.0, 0.0, 20.0 - 6 * np.pi], atol=1e-9)
    assert_allclose(p[1], p[0], atol=1e-9)
    # and as yourdfpy turns it, with the other joints off zero
    model = yourdfpy.URDF.load(io.BytesIO(text.encode()), load_meshes=False)
    q_any = np.array([0.3, -0.2, 0.4, 1.0, -0.5, 20.0])
    model.update_cfg(dict(zip(chain.joint_names, q_any, strict=True)))
    expected = model.get_transform(chain.tip_link, chain.base_link)
    R_any, p_any = chain.flange_poses(q_any[None, :])
    assert_allclose(R_any[0], expected[:3, :3], atol=1e-9)
    assert_allclose(p_any[0], expected[:3, 3] * 1000.0, atol=1e-6)


def test_a_branching_chain_asks_for_the_tip_link() -> None:
    text = _with_joint(
        "finger_a",
        '<joint name="finger_a_joint" type="revolute"><parent link="link_6"/>'
        '<child link="finger_a"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>',
    )
    text = text.replace(
        "</robot>",
        '<link name="finger_b"/><joint name="finger_b_joint" type="revolute">'
        '<parent link="link_6"/><child link="finger_b"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>',
    )
    error = _refused({"urdf": text})
    assert "branches" in error.detail
    assert error.loc == ("kinematics", "tip_link")
    assert _chain(text, tip_link="tool0").n_joints == 6
