"""Orientation and laser methods over HTTP: a torch calibrated with laser_beam comes back in
KUKA and ABB formats with the right A, B, C / quaternion."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_to_format
from app.vendors.registry import parse_controller_text
from testbed.sim.frames import translation_directions, two_point_touches, world_aligned_rotation
from testbed.sim.laser import DEVICE, TOOL_STATES, simulate, tool_down_rotation
from testbed.sim.touches import simulate_touches
from tests.conftest import Api

#: The paper's tool states as testbed/sim/laser.py builds them: (offset dX, dY mm), (runout
#: tx, ty deg), length 150 mm from the flange plane to the tip.
TRUTH = {
    "ideal": ((0.0, 0.0), (0.0, 0.0)),
    "offset": ((0.8, -0.5), (0.0, 0.0)),
    "runout": ((0.0, 0.0), (1.2, -0.7)),
    "offset_runout": ((-0.6, 0.9), (-0.9, 1.5)),
}


def _elementary(axis: str, deg: float) -> np.ndarray:
    """A rotation about one axis, written out (an independent check of the exporter)."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return {
        "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


DEVICE_NUMBERS = {
    "beam_a_y_mm": DEVICE.beam_a_y_mm,
    "beam_b_x_mm": DEVICE.beam_b_x_mm,
    "plane_z_mm": DEVICE.plane_z_mm,
}


def _laser_body(data: Any, laser: dict[str, Any], **extra: Any) -> dict[str, Any]:
    pose = pose_to_format("xyz_wxyz", data.flange_rotation, np.array([420.0, -150.0, 250.0]))
    return {
        "method": "laser_beam",
        "format": "xyz_wxyz",
        "poses": [pose],
        "laser": laser,
        "sweeps": [
            {
                "beam": s.beam,
                "break_mm": list(map(float, s.break_mm)),
                "restore_mm": list(map(float, s.restore_mm)),
            }
            for s in data.sweeps
        ],
        "descent_mm": [float(v) for v in data.descent_mm],
        **extra,
    }


@pytest.fixture
def torch(api: Api) -> dict[str, Any]:
    robot = api.robot("welder", vendor="KUKA")
    return api.tool(robot["id"], "torch", slot=4, load={"mass_kg": 3.2, "cog_mm": [0, 0, 90]})


@pytest.mark.parametrize("state", sorted(TOOL_STATES))
def test_laser_torch_version_in_kuka_and_abb(api: Api, torch: dict[str, Any], state: str) -> None:
    tool = TOOL_STATES[state]
    data = simulate(tool, flange_rotation=tool_down_rotation((2.0, -1.0), 30.0))
    response = api.post(
        f"/v1/tools/{torch['id']}/calibrations",
        _laser_body(data, DEVICE_NUMBERS),
        scope="calibrate",
    )
    assert response.status_code == 201, response.text
    cal = response.json()
    assert (cal["status"], cal["version"], cal["active"]) == ("accepted", 1, True)
    tip = tool.axis_point_mm + tool.length_mm * tool.axis_direction
    assert np.allclose(cal["tcp"]["position_mm"], tip, atol=1e-6)
    z_axis = Rotation.from_quat(cal["tcp"]["quaternion"], scalar_first=True).apply([0, 0, 1])
    assert np.allclose(z_axis, tool.axis_direction, atol=1e-9)
    offset, runout = TRUTH[state]
    assert np.allclose(cal["runout_deg"], runout, atol=1e-9)
    assert np.allclose(cal["offset_mm"], offset, atol=1e-9)
    assert abs(cal["tool_length_mm"] - 150.0) < 1e-9
    assert np.allclose(cal["widths_mm"], 2 * tool.radius_mm, atol=0.2)  # tilt widens slightly

    kuka = api.get(f"/v1/tools/{torch['id']}/tcp?format=kuka").json()["controller"]
    position, quaternion = parse_controller_text("kuka", kuka["text"])
    assert np.allclose(position, tip, atol=1e-5)
    expected = Rotation.from_quat(cal["tcp"]["quaternion"], scalar_first=True)
    got = Rotation.from_quat(quaternion, scalar_first=True)
    assert (expected.inv() * got).magnitude() < np.radians(1e-5)
    a, b, c = (kuka["values"][k] for k in "ABC")
    from_text = _elementary("z", a) @ _elementary("y", b) @ _elementary("x", c)
    assert np.allclose(from_text[:, 2], tool.axis_direction, atol=1e-7)  # tool Z = the axis
    if state in {"ideal", "offset"}:
        assert np.allclose([a, b, c], [0.0, 0.0, 0.0], atol=1e-9)

    abb = api.get(f"/v1/tools/{torch['id']}/tcp?format=abb").json()["controller"]
    assert abb["text"].startswith("PERS tooldata torch:=[TRUE,[[")
    assert "[3.2,[0.0,0.0,90.0]" in abb["text"]
    _, abb_q = parse_controller_text("abb", abb["text"])
    assert (expected.inv() * Rotation.from_quat(abb_q, scalar_first=True)).magnitude() < 1e-7
    if state in {"ideal", "offset"}:
        assert np.allclose(abb_q, [1.0, 0.0, 0.0, 0.0], atol=1e-9)


def test_laser_device_taught_then_used(api: Api, torch: dict[str, Any]) -> None:
    robot_id = torch["robot_id"]
    ideal = TOOL_STATES["ideal"]
    api.manual(torch["id"], list(ideal.axis_point_mm + ideal.length_mm * ideal.axis_direction))
    teach = simulate(ideal)
    body = _laser_body(teach, {})
    taught = api.post(
        f"/v1/robots/{robot_id}/laser-devices",
        {
            "name": "bullseye",
            "teach": {
                "tool_id": torch["id"],
                "format": body["format"],
                "poses": body["poses"],
                "sweeps": body["sweeps"],
                "descent_mm": body["descent_mm"],
            },
        },
        scope="calibrate",
    )
    assert taught.status_code == 201, taught.text
    device = taught.json()
    assert device["source"] == "taught"
    assert abs(device["beam_a_y_mm"] - DEVICE.beam_a_y_mm) < 1e-6
    assert abs(device["beam_b_x_mm"] - DEVICE.beam_b_x_mm) < 1e-6
    assert abs(device["plane_z_mm"] - DEVICE.plane_z_mm) < 1e-6

    other = api.tool(robot_id, "torch-2", slot=5)
    bent = TOOL_STATES["offset_runout"]
    cal = api.post(
        f"/v1/tools/{other['id']}/calibrations",
        _laser_body(simulate(bent), {"device_id": device["id"]}),
        scope="calibrate",
    ).json()
    tip = bent.axis_point_mm + bent.length_mm * bent.axis_direction
    assert np.allclose(cal["tcp"]["position_mm"], tip, atol=1e-6)
    listed = api.get(f"/v1/robots/{robot_id}/laser-devices").json()["items"]
    assert [d["name"] for d in listed] == ["bullseye"]


def test_laser_refuses_sweeps_at_one_height(api: Api, torch: dict[str, Any]) -> None:
    data = simulate(TOOL_STATES["ideal"], heights_mm=(200.0, 202.0))
    response = api.post(
        f"/v1/tools/{torch['id']}/calibrations",
        _laser_body(data, DEVICE_NUMBERS),
        scope="calibrate",
    )
    assert response.status_code == 422
    assert response.json()["type"].endswith("/invalid-sweep")
    assert api.get(f"/v1/tools/{torch['id']}/versions").json()["items"] == []


def test_tcp_z_x_gives_position_and_frame(api: Api, torch: dict[str, Any]) -> None:
    touches = simulate_touches(8, seed=41, touch_noise_mm=0.0)
    Q = Rotation.from_euler("xyz", [10, -20, 35], degrees=True).as_matrix()
    R = tool_down_rotation((5.0, 5.0), 10.0)
    directions = translation_directions(Q, R)
    body = {
        "method": "tcp_z_x",
        "format": "xyz_wxyz",
        "poses": [
            pose_to_format("xyz_wxyz", r, f) for r, f in zip(touches.R, touches.f, strict=True)
        ],
        "directions": [
            {
                "axis": d.axis,
                "from": pose_to_format("xyz_wxyz", d.rotation_from, d.position_from_mm),
                "to": pose_to_format("xyz_wxyz", d.rotation_to, d.position_to_mm),
            }
            for d in directions
        ],
    }
    cal = api.post(f"/v1/tools/{torch['id']}/calibrations", body, scope="calibrate").json()
    assert np.allclose(cal["tcp"]["position_mm"], touches.t, atol=1e-9)
    got = Rotation.from_quat(cal["tcp"]["quaternion"], scalar_first=True).as_matrix()
    assert np.allclose(got, Q, atol=1e-9)
    assert cal["orientation_change_deg"] is None  # no earlier orientation


def test_abc_2point_uses_active_tcp_and_reports_change(api: Api, torch: dict[str, Any]) -> None:
    t = np.array([0.0, 0.0, 180.0])
    api.manual(torch["id"], list(t))  # identity orientation, position trusted
    Q = Rotation.from_euler("y", 90, degrees=True).as_matrix()  # KUKA: tool X along flange -Z
    rotations, positions = two_point_touches(Q, t, working_axis="x")
    body = {
        "method": "abc_2point",
        "format": "xyz_wxyz",
        "poses": [
            pose_to_format("xyz_wxyz", r, f) for r, f in zip(rotations, positions, strict=True)
        ],
    }
    cal = api.post(f"/v1/tools/{torch['id']}/calibrations", body, scope="calibrate").json()
    assert cal["tcp"]["position_mm"] == [0.0, 0.0, 180.0]
    got = Rotation.from_quat(cal["tcp"]["quaternion"], scalar_first=True).as_matrix()
    assert np.allclose(got, Q, atol=1e-9)
    assert abs(cal["orientation_change_deg"] - 90.0) < 1e-9
    assert cal["version"] == 2


def test_abc_2point_without_tcp_is_422(api: Api, torch: dict[str, Any]) -> None:
    rotations, positions = two_point_touches(np.eye(3), np.array([0, 0, 150.0]))
    body = {
        "method": "abc_2point",
        "format": "xyz_wxyz",
        "poses": [
            pose_to_format("xyz_wxyz", r, f) for r, f in zip(rotations, positions, strict=True)
        ],
    }
    response = api.post(f"/v1/tools/{torch['id']}/calibrations", body, scope="calibrate")
    assert response.status_code == 422
    assert response.json()["errors"][0]["loc"] == ["body", "options", "tcp_mm"]


def test_abc_world_6d(api: Api, torch: dict[str, Any]) -> None:
    Q = Rotation.from_euler("zyx", [30, 60, -10], degrees=True).as_matrix()
    align = {"x": "-z", "y": "+y"}
    R = world_aligned_rotation(Q, align)
    body = {
        "method": "abc_world",
        "format": "matrix",
        "poses": [pose_to_format("matrix", R, np.array([400.0, 0.0, 300.0]))],
        "options": {"align": align, "tcp_mm": [0, 0, 200]},
    }
    cal = api.post(f"/v1/tools/{torch['id']}/calibrations", body, scope="calibrate").json()
    got = Rotation.from_quat(cal["tcp"]["quaternion"], scalar_first=True).as_matrix()
    assert np.allclose(got, Q, atol=1e-9)
    assert cal["tcp"]["position_mm"] == [0.0, 0.0, 200.0]
