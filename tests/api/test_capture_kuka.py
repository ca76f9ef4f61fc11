"""KUKA touches captured over KUKAVARPROXY, end to end (issue 39), with what the generic
capture tests cannot see: the KRC moves by an old guess of the tool ($ACT_TOOL 3, $TOOL =
$TOOL_DATA[3]) in a $BASE shifted and turned three ways, so $POS_ACT is neither the flange
nor in the robot's base frame. A TCP solved from touches of one point does not change when
every flange is moved by one rigid transform (a $BASE left out), so each captured pose is
held to the flange the simulator stands at, and each touch's readings to what the KRC
printed at it, in the session and in the calibration it becomes."""

from __future__ import annotations

import numpy as np
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
from tests.api.capture_steps import krc as krc
from tests.api.controller_rigs import Rig, kuka_rotation, rotation_of
from tests.conftest import Api
from tests.controllers.kuka_sim import KukaSimulator

#: What a KUKA pose read prints (contract v1.3, "Touches straight from the controller"), and
#: the base selected, which names the frame the robot moves in (v1.4 "Frames at the controller").
VARIABLES = (
    "$IPO_MODE", "$ACT_TOOL", "$TOOL", "$ACT_BASE", "$BASE", "$ROBROOT_C", "$POS_ACT", "$AXIS_ACT"
)  # fmt: skip
#: What 32-bit REALs printed with nine digits leave of a flange 1-2 m from $BASE's origin.
FLOAT32_MM, FLOAT32_DEG = 1e-3, 1e-3


def _printed(sim: KukaSimulator) -> dict[str, str]:
    shown = {name: sim.show_var(name) for name in VARIABLES}
    return {name: text for name, text in shown.items() if text is not None}


def test_captured_touches_are_the_flanges_the_krc_stood_at_and_keep_what_it_printed(
    api: Api, krc: Rig
) -> None:
    tool = tool_on(api, krc, "kr16")
    sid = guided_session(api, tool["id"], "kuka_abc")
    touches = simulate_touches(8, seed=39, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    printed = []
    for rotation, flange in zip(touches.R, touches.f, strict=True):
        krc.sim.set_flange(tuple(flange), rotation)
        added = api.post(f"/v1/sessions/{sid}/poses", {"capture": True}, scope="calibrate")
        assert added.status_code == 200, added.text
        printed.append(_printed(krc.sim))
    state = added.json()
    for pose, rotation, flange, shown in zip(
        state["poses"], touches.R, touches.f, printed, strict=True
    ):
        # kuka_abc: X, Y, Z, A, B, C of the flange, R = Rz(A) Ry(B) Rx(C)
        assert np.max(np.abs(np.subtract(pose[:3], flange))) <= FLOAT32_MM, (pose, flange)
        off = kuka_rotation(*pose[3:]).inv() * Rotation.from_matrix(rotation)
        assert np.degrees(off.magnitude()) <= FLOAT32_DEG, pose
        # $POS_ACT is the old tool's TCP in $BASE, far from the flange in the robot's base
        pos_act = dict(m.split(" ") for m in shown["$POS_ACT"][1:-1].split(": ")[1].split(", "))
        assert (
            np.linalg.norm([float(pos_act[k]) - f for k, f in zip("XYZ", flange, strict=True)])
            > 500
        )
    assert [t["source"] for t in state["touches"]] == ["controller"] * 8
    assert [t["readings"] for t in state["touches"]] == printed

    finish_and_type_again(api, tool["id"], sid, "kuka_abc", state, printed)


def test_the_pose_read_names_the_tool_the_krc_moves_by_and_its_joints(api: Api, krc: Rig) -> None:
    tool = tool_on(api, krc, "kr16")
    krc.sim.jog_flange(1104.25, -431.5, 622.75, -140.0, 62.0, 178.0)
    krc.sim.set_joints(-35.5, -70.25, 101.0, 12.0, 48.5, -210.0)
    read = api.get(
        f"/v1/robots/{tool['robot_id']}/controller/pose?format=kuka_abc", scope="calibrate"
    )
    assert read.status_code == 200, read.text
    body = read.json()
    assert body["joints_deg"] == [-35.5, -70.25, 101.0, 12.0, 48.5, -210.0]
    assert body["live_tool"]["number"] == 3
    frame = body["live_tool"]["frame"]
    assert np.max(np.abs(np.subtract(frame["position_mm"], OLD_GUESS[:3]))) <= 1e-9
    off = rotation_of(frame["quaternion"]).inv() * kuka_rotation(*OLD_GUESS[3:])
    assert np.degrees(off.magnitude()) <= 1e-6
    assert body["readings"] == _printed(krc.sim)
    assert np.max(np.abs(np.subtract(body["pose"][:3], (1104.25, -431.5, 622.75)))) <= FLOAT32_MM
    off = kuka_rotation(*body["pose"][3:]).inv() * kuka_rotation(-140.0, 62.0, 178.0)
    assert np.degrees(off.magnitude()) <= FLOAT32_DEG


def test_external_tcp_mode_is_refused_saying_what_to_do_and_nothing_is_kept(
    api: Api, krc: Rig
) -> None:
    tool = tool_on(api, krc, "kr16")
    sid = guided_session(api, tool["id"], "kuka_abc")
    before = api.get(f"/v1/sessions/{sid}").json()
    krc.sim.ipo_mode = "#TCP"
    refused = api.post(f"/v1/sessions/{sid}/poses", {"capture": True}, scope="calibrate")
    assert refused.status_code == 502, refused.text
    problem = refused.json()
    assert problem["type"].endswith("/controller-refused")
    assert problem["controller_message"] == "$IPO_MODE #TCP"
    assert "External TCP off" in problem["detail"], "what to do"
    assert "nothing was kept" in problem["detail"]
    assert api.get(f"/v1/sessions/{sid}").json() == before
