"""Robots whose kinematics is a URDF: validated at creation and PATCH, used at solve."""

from __future__ import annotations

from pathlib import Path

import numpy as np

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
    joints = np.radians(_random_joints_deg(8, seed=5)).tolist()
    response = api.post(
        "/v1/solve",
        {
            "method": "xyz_npoint",
            "format": "joints",
            "poses": joints,
            "kinematics": {"urdf": IRB4600},
            "tolerance": {"max_rms_mm": 1e6, "max_residual_mm": 1e6},
        },
        scope="read",
    )
    assert response.status_code == 200, response.text


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
