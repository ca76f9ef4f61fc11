"""Robots whose kinematics is a URDF: validated at creation and PATCH, used at solve."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import yourdfpy
from numpy.testing import assert_allclose

from tests.conftest import Api

DATA = Path(__file__).resolve().parents[1] / "data" / "urdf"
UR5E = (DATA / "ur5e.urdf").read_text()
IRB4600 = (DATA / "abb_irb4600_40_255.urdf").read_text()


def _random_joints_deg(n: int, seed: int) -> np.ndarray:
    """Random joint sets (deg) within every limit: the same numbers read through the URDF
    and through the DH preset must give the same flange poses, hence the same fit."""
    return np.random.default_rng(seed).uniform(-60, 60, size=(n, 6))


def test_a_urdf_robot_solves_joint_angles_in_radians_like_the_dh_preset(api: Api) -> None:
    robot = api.robot("ur5e-urdf", kinematics={"urdf": UR5E, "base_link": "base"})
    assert robot["kinematics"]["base_link"] == "base"
    joints_deg = _random_joints_deg(8, seed=4)
    body = {
        "method": "xyz_npoint",
        "options": {"algorithm": "stacked"},
        "tolerance": {"max_rms_mm": 1e6, "max_residual_mm": 1e6},
    }
    by_urdf = api.post(
        "/v1/solve",
        {
            **body,
            "format": "joints",
            "poses": np.radians(joints_deg).tolist(),
            "robot_id": robot["id"],
        },
        scope="read",
    )
    by_preset = api.post(
        "/v1/solve",
        {
            **body,
            "format": "joints",
            "poses": joints_deg.tolist(),
            "kinematics": {"preset": "ur5e"},
        },
        scope="read",
    )
    assert by_urdf.status_code == by_preset.status_code == 200, by_urdf.text
    assert np.allclose(
        by_urdf.json()["tcp"]["position_mm"], by_preset.json()["tcp"]["position_mm"], atol=1e-6
    )
    in_degrees = api.post(
        "/v1/solve",
        {
            **body,
            "format": "joints",
            "units": {"angle": "deg"},
            "poses": joints_deg.tolist(),
            "robot_id": robot["id"],
        },
        scope="read",
    )
    assert np.allclose(
        in_degrees.json()["tcp"]["position_mm"], by_urdf.json()["tcp"]["position_mm"], atol=1e-9
    )


def test_inline_urdf_kinematics_for_a_stateless_solve(api: Api) -> None:
    """Touches that meet: the IRB 4600's arm held still and its wrist turned. Its wrist axes
    (joint_4 to 6) cross at link_5's origin, so a tool point there, 135 mm behind tool0,
    stays put: its flange poses, from yourdfpy, meet to a few micrometres (the URDF's
    1.57076 rad is not quite pi/2). The solve with the URDF inline, at the default
    tolerance, finds the least-squares TCP of yourdfpy's poses."""
    rng = np.random.default_rng(5)
    wrist = rng.uniform(-1.0, 1.0, size=(8, 3))
    joints = np.column_stack([np.tile([0.3, 0.2, -0.1], (8, 1)), wrist])
    model = yourdfpy.URDF.load(io.BytesIO(IRB4600.encode()), load_meshes=False)
    rows, rhs = [], []
    for q in joints:
        model.update_cfg(dict(zip(model.actuated_joint_names, q, strict=True)))
        flange = model.get_transform("tool0", "base_link")
        rows.append(np.hstack([flange[:3, :3], -np.eye(3)]))  # R t - point = -p
        rhs.append(-flange[:3, 3] * 1000.0)
    solution = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    tcp, point = solution[:3], solution[3:]
    assert_allclose(tcp, [0.0, 0.0, -135.0], atol=0.01)
    response = api.post(
        "/v1/solve",
        {
            "method": "xyz_npoint",
            "options": {"algorithm": "stacked"},
            "format": "joints",
            "poses": joints.tolist(),
            "kinematics": {"urdf": IRB4600},
        },
        scope="read",
    )
    assert response.status_code == 200, response.text
    result = response.json()
    assert result["status"] == "accepted"
    assert_allclose(result["tcp"]["position_mm"], tcp, atol=1e-6)
    assert_allclose(result["reference_point_mm"], point, atol=1e-6)
    assert result["quality"]["rms_mm"] < 0.01


def test_a_joint_outside_its_limits_is_refused_naming_it(api: Api) -> None:
    robot = api.robot("irb4600", kinematics={"urdf": IRB4600})
    joints = np.zeros((6, 6))
    joints[:, 0] = np.linspace(-0.5, 0.5, 6)
    joints[4, 1] = np.radians(170.0)
    response = api.post(
        "/v1/solve",
        {
            "method": "xyz_npoint",
            "format": "joints",
            "poses": joints.tolist(),
            "robot_id": robot["id"],
        },
        scope="read",
    )
    assert response.status_code == 422
    problem = response.json()
    assert problem["type"].endswith("/out-of-range")
    assert "joint 'joint_2'" in problem["detail"]
    assert problem["errors"][0]["loc"] == ["body", "poses", 4, "joints"]


def test_bad_urdfs_are_refused_at_creation_and_patch_naming_the_problem(api: Api) -> None:
    cases = [
        (IRB4600.replace("</robot>", ""), "not well-formed XML", "urdf"),
        ({"urdf": IRB4600, "tip_link": "flange"}, "no link 'flange'", "tip_link"),
        (
            IRB4600.replace(
                '<joint name="joint_6" type="revolute">',
                '<joint name="joint_6" type="revolute"><mimic joint="joint_5"/>',
            ),
            "mimics joint 'joint_5'",
            "urdf",
        ),
    ]
    robot = api.robot("irb")
    for spec, words, field in cases:
        kinematics = spec if isinstance(spec, dict) else {"urdf": spec}
        for response in (
            api.post("/v1/robots", {"name": f"bad-{field}", "kinematics": kinematics}),
            api.patch(f"/v1/robots/{robot['id']}", {"kinematics": kinematics}),
        ):
            assert response.status_code == 422, response.text
            problem = response.json()
            assert problem["type"].endswith("/invalid-kinematics")
            assert words in problem["detail"]
            assert problem["errors"][0]["loc"] == ["body", "kinematics", field]
    assert api.get(f"/v1/robots/{robot['id']}").json()["kinematics"] is None
