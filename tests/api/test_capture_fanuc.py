"""FANUC touches captured over RMI, end to end (issue 39), with what the generic capture
tests cannot see: the controller moves by an old guess of the tool (UTOOL 3) in a user frame
(UFRAME 2) shifted and turned three ways, so FRC_ReadCartesianPosition's Position is neither
the flange nor in the world frame. A TCP solved from touches of one point does not change
when every flange is moved by one rigid transform (a UFRAME left out), so each captured pose
is held to the flange the simulator stands at, and each touch's readings to the reply lines
the controller sent at it, in the session and in the calibration it becomes."""

from __future__ import annotations

import json
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
from tests.controllers.fanuc_sim import FanucSimulator

#: UFRAME[2]: a fixture's frame, shifted and turned three ways.
UFRAME = (1200.0, -400.0, 50.0, 25.0, -3.0, 1.5)
#: The replies a FANUC pose read keeps, in the order it asks (B-84184EN 2.3.14, 2.3.15,
#: 2.3.8, 2.3.10).
COMMANDS = (
    "FRC_ReadCartesianPosition",
    "FRC_ReadJointAngles",
    "FRC_ReadUFrameData",
    "FRC_ReadUToolData",
)
#: What 32-bit REALs leave of a flange 1-2 m from the user frame's origin.
FLOAT32_MM, FLOAT32_DEG = 1e-3, 1e-3


@pytest.fixture
def controller() -> Iterator[Rig]:
    with rig("fanuc_rmi") as r:
        r.sim.set_tool(3, *OLD_GUESS)
        r.sim.set_uframe(2, *UFRAME)
        r.sim.select(uframe=2, utool=3)
        yield r


def _printed(sim: FanucSimulator) -> dict[str, str]:
    """The last reply line the controller sent to each pose read."""
    last: dict[str, str] = {}
    for line in sim.replies:
        command = json.loads(line).get("Command")
        if command in COMMANDS:
            last[command] = line
    return {command: last[command] for command in COMMANDS}


def test_captured_touches_are_the_flanges_the_robot_stood_at_and_keep_what_it_sent(
    api: Api, controller: Rig
) -> None:
    tool = tool_on(api, controller, "m20")
    sid = guided_session(api, tool["id"], "fanuc_wpr")
    touches = simulate_touches(8, seed=39, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    printed = []
    for rotation, flange in zip(touches.R, touches.f, strict=True):
        controller.sim.set_flange(tuple(flange), rotation)
        added = api.post(f"/v1/sessions/{sid}/poses", {"capture": True}, scope="calibrate")
        assert added.status_code == 200, added.text
        printed.append(_printed(controller.sim))
    state = added.json()
    for pose, rotation, flange, shown in zip(
        state["poses"], touches.R, touches.f, printed, strict=True
    ):
        # fanuc_wpr: X, Y, Z, W, P, R of the flange, R = Rz(R) Ry(P) Rx(W)
        assert np.max(np.abs(np.subtract(pose[:3], flange))) <= FLOAT32_MM, (pose, flange)
        off = fanuc_rotation(*pose[3:]).inv() * Rotation.from_matrix(rotation)
        assert np.degrees(off.magnitude()) <= FLOAT32_DEG, pose
        # Position is the old tool's TCP in UFRAME 2, far from the flange in the world
        position = json.loads(shown["FRC_ReadCartesianPosition"])["Position"]
        assert np.linalg.norm([position[k] - f for k, f in zip("XYZ", flange, strict=True)]) > 500
    assert [t["source"] for t in state["touches"]] == ["controller"] * 8
    assert [t["readings"] for t in state["touches"]] == printed

    finish_and_type_again(api, tool["id"], sid, "fanuc_wpr", state, printed)


def test_the_pose_read_names_the_utool_the_robot_moves_by_and_its_joints(
    api: Api, controller: Rig
) -> None:
    tool = tool_on(api, controller, "m20")
    controller.sim.jog_flange(1104.25, -431.5, 622.75, -140.0, 62.0, 178.0)
    controller.sim.set_joints(-35.5, -70.25, 101.0, 12.0, 48.5, -210.0)
    read = api.get(
        f"/v1/robots/{tool['robot_id']}/controller/pose?format=fanuc_wpr", scope="calibrate"
    )
    assert read.status_code == 200, read.text
    body = read.json()
    assert body["joints_deg"] == [-35.5, -70.25, 101.0, 12.0, 48.5, -210.0]
    assert body["live_tool"]["number"] == 3
    frame = body["live_tool"]["frame"]
    assert np.max(np.abs(np.subtract(frame["position_mm"], OLD_GUESS[:3]))) <= 1e-9
    off = rotation_of(frame["quaternion"]).inv() * fanuc_rotation(*OLD_GUESS[3:])
    assert np.degrees(off.magnitude()) <= 1e-5  # UTOOL's W P R held as 32-bit REALs
    assert body["readings"] == _printed(controller.sim)
    assert np.max(np.abs(np.subtract(body["pose"][:3], (1104.25, -431.5, 622.75)))) <= FLOAT32_MM
    off = fanuc_rotation(*body["pose"][3:]).inv() * fanuc_rotation(-140.0, 62.0, 178.0)
    assert np.degrees(off.magnitude()) <= FLOAT32_DEG
