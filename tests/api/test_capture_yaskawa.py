"""Yaskawa touches captured over HSES, end to end (issue 40), with what the generic capture
tests cannot see: the controller moves by an old guess of the tool (tool 3 of TOOL.CND), so
the position read (0x75, R1 cartesian, base frame) is that guess's TCP, not the flange, and
it is printed in µm and 0.0001 deg. Each captured pose is held to the flange the simulator
stands at within what those units leave, each touch keeps what the controller sent, and the
8 touches solve to the true TCP within 0.01 mm."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from testbed.sim.touches import simulate_touches
from tests.api.capture_steps import (
    OLD_GUESS,
    POINT,
    TRUE_TCP,
    finish_and_type_again,
    guided_session,
    tool_on,
)
from tests.api.controller_rigs import Rig, fanuc_rotation, rig, rotation_of
from tests.conftest import Api

#: What the position read's µm and 0.0001 deg leave of a flange (the TCP 170 mm away).
READ_MM, READ_DEG = 2e-3, 2e-4


@pytest.fixture
def controller() -> Iterator[Rig]:
    with rig("yaskawa_hses") as r:
        r.sim.set_tool(3, OLD_GUESS[:3], OLD_GUESS[3:], name="OLD GUESS")
        r.sim.select_tool(3)
        yield r


def _place(r: Rig, rotation: np.ndarray, flange: np.ndarray) -> None:
    matrix = np.eye(4)
    matrix[:3, :3] = rotation
    matrix[:3, 3] = flange
    r.sim.set_flange(matrix)


def test_captured_touches_are_the_flanges_the_robot_stood_at_and_solve_to_the_tcp(
    api: Api, controller: Rig
) -> None:
    tool = tool_on(api, controller, "gp12")
    sid = guided_session(api, tool["id"], "fanuc_wpr")
    touches = simulate_touches(8, seed=40, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    printed = []
    for rotation, flange in zip(touches.R, touches.f, strict=True):
        _place(controller, rotation, flange)
        added = api.post(f"/v1/sessions/{sid}/poses", {"capture": True}, scope="calibrate")
        assert added.status_code == 200, added.text
        printed.append(added.json()["touches"][-1]["readings"])
    state = added.json()
    for pose, rotation, flange, shown in zip(
        state["poses"], touches.R, touches.f, printed, strict=True
    ):
        # fanuc_wpr: X, Y, Z, W, P, R of the flange, R = Rz(R) Ry(P) Rx(W)
        assert np.max(np.abs(np.subtract(pose[:3], flange))) <= READ_MM, (pose, flange)
        off = fanuc_rotation(*pose[3:]).inv() * Rotation.from_matrix(rotation)
        assert np.degrees(off.magnitude()) <= READ_DEG, pose
        # the position read is the old guess's TCP, 170 mm from the flange, with its number
        words = shown["0x75 R1 cartesian (base)"].split()
        assert words[:6] == ["type", "16", "form", "0", "tool", "3"]
        read = [float(words[i]) for i in (9, 11, 13)]
        assert 150 < np.linalg.norm(np.subtract(read, flange)) < 190
        assert shown["TOOL.CND //TOOL 3"] == "4.000,-2.500,170.000,10.0000,-5.0000,3.0000"
    assert [t["source"] for t in state["touches"]] == ["controller"] * 8

    finish_and_type_again(api, tool["id"], sid, "fanuc_wpr", state, printed)


def test_the_pose_read_names_the_tool_the_robot_moves_by(api: Api, controller: Rig) -> None:
    tool = tool_on(api, controller, "gp12")
    flange = fanuc_rotation(-140.0, 62.0, 178.0).as_matrix()
    _place(controller, flange, np.array([1104.25, -431.5, 622.75]))
    read = api.get(
        f"/v1/robots/{tool['robot_id']}/controller/pose?format=fanuc_wpr", scope="calibrate"
    )
    assert read.status_code == 200, read.text
    body = read.json()
    assert body["joints_deg"] is None  # HSES serves pulses, not the degrees per pulse
    assert body["protocol"] == "yaskawa_hses"
    assert body["live_tool"]["number"] == 3
    frame = body["live_tool"]["frame"]
    assert np.max(np.abs(np.subtract(frame["position_mm"], OLD_GUESS[:3]))) <= 1e-9
    off = rotation_of(frame["quaternion"]).inv() * fanuc_rotation(*OLD_GUESS[3:])
    assert np.degrees(off.magnitude()) <= 1e-9
    assert np.max(np.abs(np.subtract(body["pose"][:3], (1104.25, -431.5, 622.75)))) <= READ_MM
    off = fanuc_rotation(*body["pose"][3:]).inv() * fanuc_rotation(-140.0, 62.0, 178.0)
    assert np.degrees(off.magnitude()) <= READ_DEG
    assert set(body["readings"]) == {
        "0x75 R1 cartesian (base)",
        "0x75 R1 pulses",
        "TOOL.CND //TOOL 3",
    }
