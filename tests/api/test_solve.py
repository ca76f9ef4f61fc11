"""POST /v1/solve and GET /v1/methods: stateless, every pose format, nothing stored."""

from __future__ import annotations

import numpy as np
import pytest

from app.jsontypes import JsonObject
from app.kinematics.dh import flange_poses
from app.kinematics.poses import POSE_FORMATS
from app.vendors.registry import PRESETS
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses, row_counts
from tests.conftest import TABLES, Api

#: Every pose format but joints (solved through kinematics in the tests below): a format
#: added to app.words.PoseFormat is held to the same TCP here without being listed again.
FORMATS = [fmt for fmt in POSE_FORMATS if fmt != "joints"]


def _solve(api: Api, body: JsonObject) -> JsonObject:
    response = api.post("/v1/solve", body, scope="read")
    assert response.status_code == 200, response.text
    return dict(response.json())


def test_same_touches_in_every_format_give_the_same_tcp(api: Api) -> None:
    touches = simulate_touches(8, seed=31, touch_noise_mm=0.05)
    before = row_counts(TABLES)
    results = {
        fmt: _solve(api, {"method": "xyz_npoint", "format": fmt, "poses": as_poses(touches, fmt)})[
            "tcp"
        ]["position_mm"]
        for fmt in FORMATS
    }
    reference = np.asarray(results["matrix"])
    for fmt, tcp in results.items():
        assert np.allclose(tcp, reference, atol=1e-6), fmt
    assert row_counts(TABLES) == before


def test_a_stateless_result_is_a_calibration_document_that_nothing_stores(api: Api) -> None:
    touches = simulate_touches(8, seed=33, touch_noise_mm=0.05)
    body = {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(touches, "xyz_wxyz")}
    result = _solve(api, {**body, "activate": "always"})
    assert (result["id"], result["version"], result["active"]) == (None, None, False)
    assert result["status"] == "accepted"
    assert result["quality"]["n_poses"] == 8
    assert result["summary"]
    assert result["warnings"] == ["activate 'always' ignored: /v1/solve stores nothing"]
    stored = api.post(f"/v1/tools/{_tool(api)}/calibrations", body, scope="calibrate").json()
    assert set(result) == set(stored) - {"tool_id", "created_at", "created_by"}


def _tool(api: Api) -> str:
    return str(api.tool(api.robot()["id"])["id"])


def test_noise_free_solve_recovers_truth_to_1e9(api: Api) -> None:
    touches = simulate_touches(6, seed=32, touch_noise_mm=0.0)
    for algorithm in ("robust", "stacked", "pairwise", "sphere", "gls"):
        options: dict[str, object] = {"algorithm": algorithm}
        if algorithm == "gls":
            options |= {"touch_noise_mm": 0.05, "orientation_noise_deg": 0.02}
        result = _solve(
            api,
            {
                "method": "xyz_npoint",
                "format": "matrix",
                "poses": as_poses(touches, "matrix"),
                "options": options,
            },
        )
        assert np.allclose(result["tcp"]["position_mm"], touches.t, atol=1e-9), algorithm
        assert result["algorithm"] == algorithm


def test_units_override_for_a_ur_pendant_showing_degrees(api: Api) -> None:
    touches = simulate_touches(8, seed=33, touch_noise_mm=0.0)
    poses = as_poses(touches, "ur_rotvec")
    in_degrees = [[*p[:3], *np.degrees(p[3:])] for p in poses]
    plain = _solve(api, {"method": "xyz_npoint", "format": "ur_rotvec", "poses": poses})
    degrees = _solve(
        api,
        {
            "method": "xyz_npoint",
            "format": "ur_rotvec",
            "poses": in_degrees,
            "units": {"angle": "deg"},
        },
    )
    assert np.allclose(plain["tcp"]["position_mm"], touches.t, atol=1e-6)
    assert np.allclose(degrees["tcp"]["position_mm"], touches.t, atol=1e-6)
    wrong = api.post(
        "/v1/solve",
        {"method": "xyz_npoint", "format": "ur_rotvec", "poses": in_degrees},
        scope="read",
    )
    # degrees read as radians: either refused or clearly not the same TCP
    if wrong.status_code == 200:
        assert not np.allclose(wrong.json()["tcp"]["position_mm"], touches.t, atol=1.0)
    else:
        assert wrong.status_code == 422


# Three intersecting joint axes (a spherical joint at the base origin) and the flange
# 150 mm back along the last axis: whatever the joints, TCP (0, 0, 150) sits at the origin.
PIVOT_ARM = {
    "convention": "dh",
    "links": [
        {"a": 0, "alpha": 90, "d": 0},
        {"a": 0, "alpha": -90, "d": 0},
        {"a": 0, "alpha": 0, "d": -150},
    ],
}


def test_joints_through_inline_kinematics_and_through_the_robot(api: Api) -> None:
    joints = np.random.default_rng(7).uniform(-70, 70, size=(8, 3)).tolist()
    inline = _solve(
        api, {"method": "xyz_npoint", "format": "joints", "poses": joints, "kinematics": PIVOT_ARM}
    )
    assert np.allclose(inline["tcp"]["position_mm"], [0, 0, 150], atol=1e-9)
    assert np.allclose(inline["reference_point_mm"], [0, 0, 0], atol=1e-9)
    robot = api.robot("pivot-arm", kinematics=PIVOT_ARM)
    by_robot = _solve(
        api, {"method": "xyz_npoint", "format": "joints", "poses": joints, "robot_id": robot["id"]}
    )
    assert by_robot["tcp"] == inline["tcp"]
    radians = _solve(
        api,
        {
            "method": "xyz_npoint",
            "format": "joints",
            "units": {"angle": "rad"},
            "poses": np.radians(joints).tolist(),
            "kinematics": PIVOT_ARM,
        },
    )
    assert np.allclose(radians["tcp"]["position_mm"], [0, 0, 150], atol=1e-9)


def test_ur5e_preset_joints_solve_like_their_flange_poses(api: Api) -> None:
    joints = np.random.default_rng(8).uniform(-60, 60, size=(8, 6))
    R, f = flange_poses(PRESETS["ur5e"], joints)
    matrices = [
        np.vstack([np.hstack([r, p[:, None]]), [0, 0, 0, 1]]).tolist()
        for r, p in zip(R, f, strict=True)
    ]
    body = {
        "method": "xyz_npoint",
        "options": {"algorithm": "stacked"},
        "tolerance": {"max_rms_mm": 1e6, "max_residual_mm": 1e6},
    }
    by_joints = api.post(
        "/v1/solve",
        {**body, "format": "joints", "poses": joints.tolist(), "kinematics": {"preset": "ur5e"}},
        scope="read",
    )
    by_matrix = api.post("/v1/solve", {**body, "format": "matrix", "poses": matrices}, scope="read")
    assert by_joints.status_code == by_matrix.status_code == 200, by_joints.text
    assert np.allclose(
        by_joints.json()["tcp"]["position_mm"], by_matrix.json()["tcp"]["position_mm"], atol=1e-6
    )


def test_joints_without_kinematics_is_422_saying_so(api: Api) -> None:
    robot = api.robot("bare")
    tool = api.tool(robot["id"])
    response = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        {"method": "xyz_npoint", "format": "joints", "poses": [[0, 0, 0, 0, 0, 0]] * 4},
        scope="calibrate",
    )
    assert response.status_code == 422
    assert response.json()["type"].endswith("/missing-kinematics")
    assert "kinematics" in response.json()["detail"]


def test_stateless_reference_needs_numbers(api: Api) -> None:
    pose = [500, 0, 400, 0, 1, 0, 0]
    ok = _solve(
        api,
        {
            "method": "xyz_reference",
            "format": "xyz_wxyz",
            "poses": [pose],
            "options": {"reference_point_mm": [500, 0, 300]},
        },
    )
    assert np.allclose(ok["tcp"]["position_mm"], [0, 0, 100], atol=1e-9)
    refused = api.post(
        "/v1/solve",
        {
            "method": "xyz_reference",
            "format": "xyz_wxyz",
            "poses": [pose],
            "options": {"reference_point_id": "p1"},
        },
        scope="read",
    )
    assert refused.status_code == 422
    assert refused.json()["errors"][0]["loc"] == ["body", "options", "reference_point_id"]


@pytest.mark.parametrize("fmt", ["matrix", "xyz_wxyz"])
def test_bad_rotations_are_refused_with_pose_index(api: Api, fmt: str) -> None:
    touches = simulate_touches(5, seed=34, touch_noise_mm=0.0)
    poses = as_poses(touches, fmt)
    if fmt == "matrix":
        poses[2][0][0] *= 1.1
    else:
        poses[2][3] *= 1.1
    response = api.post(
        "/v1/solve", {"method": "xyz_npoint", "format": fmt, "poses": poses}, scope="read"
    )
    assert response.status_code == 422
    problem = response.json()
    assert problem["type"].endswith("/invalid-rotation")
    assert problem["errors"][0]["loc"][:3] == ["body", "poses", 2]


def test_methods_lists_every_method_with_defaults(api: Api) -> None:
    items = {m["name"]: m for m in api.get("/v1/methods").json()["items"]}
    assert set(items) == {
        "xyz_npoint",
        "xyz_plane",
        "xyz_reference",
        "tcp_z_x",
        "abc_2point",
        "abc_world",
        "laser_beam",
        "manual",
    }
    assert items["xyz_npoint"]["min_poses"] == 4
    assert items["xyz_npoint"]["options"]["algorithm"]["default"] == "robust"
    assert items["abc_2point"]["options"]["working_axis"]["default"] == "x"
    assert "directions" in items["tcp_z_x"]["requires"]
    assert items["xyz_reference"]["max_poses"] == 1
    assert items["manual"]["min_poses"] == 0
