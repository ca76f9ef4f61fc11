"""The robot makers' presets against the makers' own URDFs (kept in tests/data/urdf/, sources and
licences in tests/data/README.md): each DH preset's flange pose equals the URDF's forward
kinematics, computed by yourdfpy, to 1e-6 mm and 1e-9 rad over seeded random joints within
the URDF's limits; and the same URDF read as a robot's `kinematics` gives the preset's poses.

The URDFs round the right angles of their fixed frames (Techman: pi/2 as 1.570796; ROS-
Industrial's GP12 flange: pi as 3.1415926 and pi/2 as 1.570796), 3.3e-7 rad off. The 1e-9
comparison is made with those values snapped to the multiple of pi/2 they stand for (any rpy
value within 1e-6 rad of one); the files as published are compared within what the rounding
explains (the sum of the values' roundings, times the arm's reach for a position).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from lxml import etree

from app.kinematics.dh import flange_poses, kinematics_from_spec
from app.kinematics.urdf import UrdfChain
from app.vendors.registry import PRESETS

DATA = Path(__file__).resolve().parents[1] / "data" / "urdf"
HALF_PI = math.pi / 2
#: An rpy value this close (rad) to a multiple of pi/2 is that multiple, rounded in the file.
SNAP_RAD = 1e-6
#: Farther than any point of these arms reaches from its base (mm), for the rounding's bound.
REACH_MM = 1500.0


@dataclass(frozen=True)
class MakersUrdf:
    """A preset and the maker's URDF it is derived from: which links are the controller's base
    frame and its flange."""

    preset: str
    file: str
    base_link: str
    tip_link: str
    #: rpy values the file rounds (the count, so that a new copy rounding otherwise is noticed)
    rounded: int


CASES = [
    # Techman: `base` (= link_0, the robot base frame) to tool0 (= flange_link = link_6).
    MakersUrdf("tm5_900", "tm5-900-nominal.urdf", "base", "tool0", rounded=5),
    # Yaskawa: `base`, the robot coordinates 450 mm above base_link, to tool0, the flange.
    MakersUrdf("yaskawa_gp12", "motoman_gp12.urdf", "base", "tool0", rounded=2),
]
IDS = [case.preset for case in CASES]


def _snapped(text: str) -> tuple[str, int, float]:
    """The URDF with every joint origin's rpy value within SNAP_RAD of k pi/2 set to k pi/2,
    how many values that changed and by how much in all (rad)."""
    root = etree.fromstring(text.encode())
    changed = 0
    total = 0.0
    for origin in root.iterfind("joint/origin"):
        values = [float(v) for v in origin.get("rpy", "0 0 0").split()]
        exact = [HALF_PI * round(v / HALF_PI) for v in values]
        near = [abs(v - e) < SNAP_RAD for v, e in zip(values, exact, strict=True)]
        changed += sum(n and v != e for n, v, e in zip(near, values, exact, strict=True))
        total += sum(abs(v - e) for n, v, e in zip(near, values, exact, strict=True) if n)
        snapped = [e if n else v for n, v, e in zip(near, values, exact, strict=True)]
        origin.set("rpy", " ".join(repr(v) for v in snapped))
    return etree.tostring(root, encoding="unicode"), changed, total


def _model(text: str) -> yourdfpy.URDF:
    return yourdfpy.URDF.load(
        io.BytesIO(text.encode()),
        load_meshes=False,
        build_collision_scene_graph=False,
        load_collision_meshes=False,
    )


def _random_joints(model: yourdfpy.URDF, n: int, seed: int) -> np.ndarray:
    """n joint vectors (rad), uniform within each actuated joint's URDF limits."""
    limits = [model.joint_map[name].limit for name in model.actuated_joint_names]
    low = np.array([limit.lower for limit in limits])
    high = np.array([limit.upper for limit in limits])
    return np.random.default_rng(seed).uniform(low, high, (n, len(limits)))


def _urdf_poses(
    model: yourdfpy.URDF, case: MakersUrdf, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """yourdfpy's flange poses (rotations, positions in mm) of `tip_link` in `base_link`."""
    transforms = []
    for row in q:
        model.update_cfg(dict(zip(model.actuated_joint_names, row, strict=True)))
        transforms.append(model.get_transform(frame_to=case.tip_link, frame_from=case.base_link))
    stacked = np.array(transforms)
    return stacked[:, :3, :3], stacked[:, :3, 3] * 1000.0


def _text(case: MakersUrdf) -> str:
    return (DATA / case.file).read_text()


def _preset_off_by(
    case: MakersUrdf, q: np.ndarray, rotations: np.ndarray, positions: np.ndarray
) -> tuple[float, float]:
    """How far the preset's flange poses at joints q (rad) are from the given ones: the largest
    position difference (mm) and rotation-matrix entry difference."""
    R_dh, p_dh = flange_poses(PRESETS[case.preset], np.degrees(q))
    return float(np.abs(p_dh - positions).max()), float(np.abs(R_dh - rotations).max())


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_preset_equals_its_makers_urdf(case: MakersUrdf) -> None:
    """200 seeded joint vectors within the URDF's limits (and all zero): the preset's flange
    pose is yourdfpy's base -> tool0 transform of the maker's URDF, to 1e-6 mm and 1e-9."""
    text, changed, _ = _snapped(_text(case))
    assert changed == case.rounded
    model = _model(text)
    q = np.vstack([np.zeros(6), _random_joints(model, 200, seed=40)])
    mm, turn = _preset_off_by(case, q, *_urdf_poses(model, case, q))
    assert mm < 1e-6, f"{case.preset}: flange {mm} mm off its URDF"
    assert turn < 1e-9, f"{case.preset}: flange turned off its URDF ({turn})"


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_urdf_as_published_differs_only_by_its_rounding(case: MakersUrdf) -> None:
    """The file unchanged: each right angle rounded (pi/2 by 3.3e-7 rad) turns what follows it
    by as much, so the flange is turned by at most their sum (TM5-900: five of them, 1.6e-6;
    GP12: 3.8e-7) and moved by at most that angle times the reach."""
    _, _, rounding_rad = _snapped(_text(case))
    model = _model(_text(case))
    q = _random_joints(model, 200, seed=41)
    mm, turn = _preset_off_by(case, q, *_urdf_poses(model, case, q))
    assert mm < rounding_rad * REACH_MM, f"{case.preset}: flange {mm} mm off its URDF"
    assert turn < rounding_rad, f"{case.preset}: flange turned off its URDF ({turn})"


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_the_urdf_as_a_robots_kinematics_gives_the_presets_poses(case: MakersUrdf) -> None:
    """The same (snapped) URDF given as a robot's `kinematics` from `base` to `tool0`, the
    way a client would send it, poses the flange as the preset does."""
    text, _, _ = _snapped(_text(case))
    chain = kinematics_from_spec(
        {"urdf": text, "base_link": case.base_link, "tip_link": case.tip_link}, presets=PRESETS
    )
    assert isinstance(chain, UrdfChain)
    q = _random_joints(_model(text), 200, seed=42)
    mm, turn = _preset_off_by(case, q, *chain.flange_poses(q))
    assert mm < 1e-6, f"{case.preset}: flange {mm} mm off the URDF robot's"
    assert turn < 1e-9, f"{case.preset}: flange turned off the URDF robot's ({turn})"


def test_gp12_flange_at_zero_joints_is_895_0_814_mm_in_robot_coordinates() -> None:
    """Yaskawa GP12, all joints zero: the flange 155 + 640 + 100 mm forward of the S axis and
    614 + 200 mm above the L axis (the robot coordinates' origin, 450 mm above base_link),
    its Z (the tool's direction) along the robot's X; in the preset and in the URDF."""
    rotation, position = flange_poses(PRESETS["yaskawa_gp12"], np.zeros((1, 6)))
    np.testing.assert_allclose(position[0], [895.0, 0.0, 814.0], atol=1e-9)
    np.testing.assert_allclose(rotation[0][:, 2], [1.0, 0.0, 0.0], atol=1e-12)
    case = CASES[IDS.index("yaskawa_gp12")]
    model = _model(_text(case))
    base_in_base_link = model.get_transform(frame_to="base", frame_from="base_link")
    np.testing.assert_allclose(base_in_base_link[:3, 3], [0.0, 0.0, 0.450], atol=1e-12)
    _, urdf_position = _urdf_poses(model, case, np.zeros((1, 6)))
    np.testing.assert_allclose(urdf_position[0], [895.0, 0.0, 814.0], atol=1e-9)
