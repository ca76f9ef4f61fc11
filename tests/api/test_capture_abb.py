"""ABB touches captured over RWS 1.0 and 2.0, end to end (issue 39), with what the generic
capture tests cannot see: the program last moved by an old guess of the tool (tTorch, turned)
in a work object shifted and turned three ways, on a robot whose base stands away from the
world, so the robtarget RWS gives by default (the active tool and work object) is neither
the flange nor in the robot's base frame. A TCP solved from touches of one point does not
change when every flange is moved by one rigid transform (a work object or the world frame
read in place of the base), so each captured pose is held to the flange the simulator stands
at, and each touch's readings to the values the controller's robtarget and jointtarget
answers held, in the session and in the calibration it becomes."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from testbed.sim.touches import simulate_touches
from tests.api.capture_steps import (
    POINT,
    TRUE_TCP,
    finish_and_type_again,
    guided_session,
    tool_on,
)
from tests.api.controller_rigs import SYMBOL, TIMEOUT_S, Rig, rig, rotation_of
from tests.api.controller_rigs import secret_key as secret_key  # autouse: ABB passwords
from tests.conftest import Api
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.simbase import go_silent

#: The tooldata the program last moved by: an old guess, turned (q1..q4).
ACTIVE_TOOL = ((4.0, -2.5, 170.0), (0.9659258, 0.0, 0.258819, 0.0))
#: The work object it moved in: a fixture, shifted and turned three ways.
_TURNED = Rotation.from_euler("ZYX", [25.0, -3.0, 1.5], degrees=True).as_quat()
WOBJ = (
    (1200.0, -400.0, 50.0),
    (float(_TURNED[3]), float(_TURNED[0]), float(_TURNED[1]), float(_TURNED[2])),
)
#: The robot's base in the world (a robot on a pedestal, turned half a turn).
BASE_FRAME = ((0.0, 0.0, 500.0), (0.0, 0.0, 0.0, 1.0))
#: What the connector asks for: tool0 in wobj0, Base coordinates.
FLANGE_QUERY = {"tool": "tool0", "wobj": "wobj0", "coordinate": "Base"}
#: RobotWare's nums are 32-bit floats: what they leave of a flange a metre or two out.
FLOAT32_MM, FLOAT32_DEG = 1e-3, 1e-3


@pytest.fixture(params=["abb_rws1", "abb_rws2"])
def controller(request: pytest.FixtureRequest) -> Iterator[Rig]:
    with rig(request.param) as r:
        r.sim.set_tool(SYMBOL, *ACTIVE_TOOL)
        r.sim.active_tool = SYMBOL.rsplit("/", 1)[1]
        r.sim.wobjs["wFixture"] = WOBJ
        r.sim.active_wobj = "wFixture"
        r.sim.base_frame = BASE_FRAME
        yield r


def _item(body: dict[str, Any]) -> dict[str, str]:
    """The one state item of an answer (RWS 1.0 ``_embedded._state``, 2.0 ``state``)."""
    states = body["state"] if "state" in body else body["_embedded"]["_state"]
    (item,) = states
    return {k: v for k, v in item.items() if not k.startswith("_")}


def _printed(sim: AbbRwsSimulator, query: dict[str, str] = FLANGE_QUERY) -> dict[str, str]:
    """The values the controller answers where the robot stands now."""
    status, robtarget = sim.robtarget(sim.mechunit, query)
    assert status == 200, robtarget
    _, jointtarget = sim.jointtarget(sim.mechunit)
    return (
        {f"robtarget.{k}": v for k, v in _item(robtarget).items()}
        | {f"jointtarget.{k}": v for k, v in _item(jointtarget).items()}
        # the work object the robot moves in (v1.4 "Frames at the controller")
        | {"mechunit.wobj-name": sim.active_wobj}
    )


def _place(sim: AbbRwsSimulator, rotation: np.ndarray, position: np.ndarray) -> None:
    x, y, z, w = (float(v) for v in Rotation.from_matrix(rotation).as_quat())
    sim.set_pose((float(position[0]), float(position[1]), float(position[2])), (w, x, y, z))


def test_captured_touches_are_the_flanges_the_robot_stood_at_and_keep_what_rws_answered(
    api: Api, controller: Rig
) -> None:
    tool = tool_on(api, controller, "irb2600")
    sid = guided_session(api, tool["id"], "xyz_wxyz")
    touches = simulate_touches(8, seed=39, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    printed = []
    for rotation, flange in zip(touches.R, touches.f, strict=True):
        _place(controller.sim, rotation, flange)
        added = api.post(f"/v1/sessions/{sid}/poses", {"capture": True}, scope="calibrate")
        assert added.status_code == 200, added.text
        printed.append(_printed(controller.sim))
    state = added.json()
    for pose, rotation, flange in zip(state["poses"], touches.R, touches.f, strict=True):
        # xyz_wxyz: the flange's X, Y, Z and its quaternion w, x, y, z (ABB's q1..q4)
        assert np.max(np.abs(np.subtract(pose[:3], flange))) <= FLOAT32_MM, (pose, flange)
        off = rotation_of(pose[3:]).inv() * Rotation.from_matrix(rotation)
        assert np.degrees(off.magnitude()) <= FLOAT32_DEG, pose
        # the robtarget of the active tool in the active work object is far from it
        _place(controller.sim, rotation, flange)
        active = _printed(controller.sim, {"coordinate": "Wobj"})
        xyz = [float(active[f"robtarget.{k}"]) for k in "xyz"]
        assert np.linalg.norm(np.subtract(xyz, flange)) > 500
    assert [t["source"] for t in state["touches"]] == ["controller"] * 8
    assert [t["readings"] for t in state["touches"]] == printed

    finish_and_type_again(api, tool["id"], sid, "xyz_wxyz", state, printed)


def test_the_pose_read_gives_the_joints_and_no_live_tool(api: Api, controller: Rig) -> None:
    """RWS says where the flange is and the joint angles, not which tooldata a program
    moves by: the live tool is null, with no matches."""
    tool = tool_on(api, controller, "irb2600")
    flange = (1104.25, -431.5, 622.75)
    turned = Rotation.from_euler("ZYX", [-140.0, 62.0, 178.0], degrees=True)
    _place(controller.sim, turned.as_matrix(), np.asarray(flange))
    controller.sim.joints = (-35.5, -70.25, 101.0, 12.0, 48.5, -210.0)
    read = api.get(
        f"/v1/robots/{tool['robot_id']}/controller/pose?format=xyz_wxyz", scope="calibrate"
    )
    assert read.status_code == 200, read.text
    body = read.json()
    assert body["protocol"] == controller.protocol
    assert body["joints_deg"] == [-35.5, -70.25, 101.0, 12.0, 48.5, -210.0]
    assert body["live_tool"] == {"number": None, "frame": None, "matches": []}
    assert body["readings"] == _printed(controller.sim)
    assert np.max(np.abs(np.subtract(body["pose"][:3], flange))) <= FLOAT32_MM
    off = rotation_of(body["pose"][3:]).inv() * turned
    assert np.degrees(off.magnitude()) <= FLOAT32_DEG


def test_a_controller_silent_at_the_second_read_is_502_within_its_timeout(
    api: Api, controller: Rig
) -> None:
    """The capture's first read is answered, the second is not: the 502 comes within
    timeout_s + 1 s, the logout the connector then tries included, and the session keeps
    nothing."""
    tool = tool_on(api, controller, "irb2600")
    sid = guided_session(api, tool["id"], "xyz_wxyz")
    before = api.get(f"/v1/sessions/{sid}").json()
    controller.sim.fault = go_silent(
        "before", "GET /rw/motionsystem/mechunits/ROB_1/robtarget", nth=2
    )
    started = time.monotonic()
    failed = api.post(f"/v1/sessions/{sid}/poses", {"capture": True}, scope="calibrate")
    elapsed = time.monotonic() - started
    assert failed.status_code == 502, failed.text
    assert failed.json()["type"].endswith("/controller-unreachable")
    assert elapsed < TIMEOUT_S + 1, elapsed
    assert api.get(f"/v1/sessions/{sid}").json() == before
