"""A UR robot on the line (issue 40), through the API, against the UR simulator: touches
captured over RTDE while the robot moves by an old guess of the tool (so actual_TCP_pose is not
the flange), the live tool named, a pendant-side change of the TCP flagged by the watcher
within one interval, and the refusals a cell meets (local control, a protective stop) told in
words with nothing written."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from testbed.sim.touches import simulate_touches
from tests.api.capture_steps import POINT, TRUE_TCP, finish_and_type_again, guided_session, tool_on
from tests.api.controller_rigs import Rig, rig
from tests.api.test_deployments import ACTIVE_POSITION, _setup
from tests.conftest import Api
from tests.polling import wait_for

#: The TCP the robot moves by while the touches are taken (the pendant's, an old guess):
#: x, y, z in m and a rotation vector in rad, as UR prints it.
OLD_GUESS = (0.004, -0.0025, 0.17, 0.15, -0.08, 0.05)
INTERVAL_S = 0.5


@pytest.fixture
def ur() -> Iterator[Rig]:
    """A UR controller moving by OLD_GUESS (set at the pendant)."""
    with rig("ur_rtde") as r:
        r.sim.pendant_set_tcp(OLD_GUESS)
        yield r


def test_eight_captured_touches_solve_to_the_true_tcp(api: Api, ur: Rig) -> None:
    tool = tool_on(api, ur, "ur10e")
    sid = guided_session(api, tool["id"], "ur_rotvec")
    touches = simulate_touches(8, seed=40, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    printed = []
    for rotation, flange in zip(touches.R, touches.f, strict=True):
        ur.sim.set_flange(tuple(flange), rotation)
        added = api.post(f"/v1/sessions/{sid}/poses", {"capture": True}, scope="calibrate")
        assert added.status_code == 200, added.text
        printed.append(added.json()["touches"][-1]["readings"])
    state = added.json()
    for pose, rotation, flange, shown in zip(
        state["poses"], touches.R, touches.f, printed, strict=True
    ):
        # ur_rotvec: the flange in m and a rotation vector (rad)
        assert np.max(np.abs(np.multiply(pose[:3], 1000.0) - flange)) <= 1e-6, (pose, flange)
        off = Rotation.from_rotvec(pose[3:]).inv() * Rotation.from_matrix(rotation)
        assert np.degrees(off.magnitude()) <= 1e-6
        # what the controller printed: the TCP of the old guess, not the flange
        tcp_pose = [float(v) for v in shown["actual_TCP_pose"].strip("[]").split(",")]
        assert np.linalg.norm(np.multiply(tcp_pose[:3], 1000.0) - flange) > 150
        assert shown["tcp_offset"] == "[" + ", ".join(repr(v) for v in OLD_GUESS) + "]"
    assert [t["source"] for t in state["touches"]] == ["controller"] * 8
    finish_and_type_again(api, tool["id"], sid, "ur_rotvec", state, printed)


def test_the_pose_read_names_the_live_tool_and_the_version_it_is(api: Api) -> None:
    with rig("ur_rtde") as r:
        ids = _setup(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        deployed = api.post(f"/v1/tools/{tool_id}/deployments", {}, scope="calibrate")
        assert deployed.status_code == 201, deployed.text
        r.sim.set_joints(10, -90, 100, -100, -90, 45)
        read = api.get(f"/v1/robots/{robot_id}/controller/pose", scope="calibrate")
        assert read.status_code == 200, read.text
        body = read.json()
        assert body["protocol"] == "ur_rtde"
        assert body["joints_deg"] == pytest.approx([10, -90, 100, -100, -90, 45], abs=1e-9)
        live = body["live_tool"]
        assert live["number"] is None  # UR has no tool numbers
        np.testing.assert_allclose(live["frame"]["position_mm"], ACTIVE_POSITION, atol=1e-6)
        assert live["matches"] == [{"tool_id": tool_id, "version": 1, "active": True}]


@pytest.fixture
def watching(monkeypatch: pytest.MonkeyPatch) -> float:
    """The watcher on (set before the app starts: ask for it before `api`)."""
    monkeypatch.setenv("TCPCAL_RECONCILE_INTERVAL_S", str(INTERVAL_S))
    return INTERVAL_S


def test_a_pendant_change_of_the_tcp_is_flagged_within_one_interval(
    watching: float, api: Api
) -> None:
    with rig("ur_rtde") as r:
        ids = _setup(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        deployed = api.post(f"/v1/tools/{tool_id}/deployments", {}, scope="calibrate")
        assert deployed.status_code == 201, deployed.text

        def row() -> dict[str, Any]:
            got = api.get("/v1/tools", params={"robot_id": robot_id})
            return dict(got.json()["items"][0])

        def active() -> bool:
            current = row()
            state = (current["controller"] or {}).get("state")
            return bool(current["live"]["state"] == "active" and state == "in_sync")

        wait_for(active, 2 * watching + 1.0, "moving by the deployed v1, in sync")
        assert row()["live"]["version"] == 1
        # the operator sets another TCP at the pendant
        r.sim.pendant_set_tcp((0.0, 0.0, 0.2, 0.0, 0.0, 0.0))
        started = time.monotonic()
        wait_for(
            lambda: (row()["controller"] or {}).get("state") == "drifted",
            watching + 2.0,
            "drifted",
        )
        took = time.monotonic() - started
        assert took <= watching + 1.0, took  # the next round, plus its read
        flagged = row()
        assert flagged["live"]["state"] == "unknown"
        assert "controller_drifted" in flagged["attention"]
        assert "moving_by_unknown_tcp" in flagged["attention"]


def test_a_deployment_is_live_until_a_program_start_and_the_other_tools_are_not_live(
    api: Api,
) -> None:
    """scope live: the robot moves by the deployed tool until a program is played, which
    brings the installation's TCP back; the robot's other tools are not_live."""
    with rig("ur_rtde") as r:
        ids = _setup(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        other = api.tool(robot_id, "gripper")
        done = api.post(f"/v1/tools/{tool_id}/deployments", {}, scope="calibrate")
        assert done.status_code == 201, done.text
        assert done.json()["scope"] == "live"
        assert done.json()["target"] == "tcp_offset"
        states = {t["tool_id"]: t["state"] for t in _reconcile(api, robot_id)["tools"]}
        assert states == {tool_id: "in_sync", other["id"]: "not_live"}
        r.sim.play_program()  # the program starts with the installation's TCP (zero here)
        recon = _reconcile(api, robot_id)
        states = {t["tool_id"]: t["state"] for t in recon["tools"]}
        assert states == {tool_id: "drifted", other["id"]: "not_live"}
        assert recon["live_tool"]["frame"]["position_mm"] == [0.0, 0.0, 0.0]


def _reconcile(api: Api, robot_id: str) -> dict[str, Any]:
    done = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    assert done.status_code == 200, done.text
    return dict(done.json())


def _deploy_refused(api: Api, r: Rig) -> dict[str, Any]:
    ids = _setup(api, r)
    failed = api.post(f"/v1/tools/{ids['tool']['id']}/deployments", {}, scope="calibrate")
    assert failed.status_code == 502, failed.text
    problem: dict[str, Any] = failed.json()
    assert problem["type"].endswith("/controller-refused")
    assert problem["deployment_status"] == "not_written"
    assert "nothing was written" in problem["detail"]
    return problem


def test_local_control_is_refused_in_words_with_nothing_written(api: Api) -> None:
    with rig("ur_rtde") as r:
        before = r.sim.tcp()
        r.sim.remote_control(False)
        problem = _deploy_refused(api, r)
        assert problem["controller_message"].startswith("C210A0")
        assert "Remote Control" in problem["detail"]
        assert r.sim.tcp() == before
        assert [p.refused is not None for p in r.sim.programs] == [True]


def test_a_protective_stop_is_refused_before_anything_is_sent(api: Api) -> None:
    with rig("ur_rtde") as r:
        r.sim.protective_stop()
        problem = _deploy_refused(api, r)
        assert "protective stop" in problem["controller_message"]
        assert "release the stop" in problem["detail"]
        assert r.sim.programs == []
