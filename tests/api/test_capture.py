"""Touches straight from the controller (contract v1.3), the service's logic against a fake
connector: the still check (two reads at least 100 ms apart), the conversion to the
session's format, the refusals (409 /robot-moving, 502 as for deployments) with nothing
kept, touch sources kept by the session and the calibration it finishes, captured checks,
and the tool's sessions newest first."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_from_format
from app.vendors.connector import (
    ClosingSession,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    Frame,
    LiveTool,
    PoseReading,
)
from testbed.sim.touches import simulate_touches
from tests.api.touches import row_counts
from tests.conftest import Api

TOUCHES = simulate_touches(8, seed=39, touch_noise_mm=0.0, tcp_mm=np.array([4.0, -7.0, 165.0]))


def _reading(rotation: np.ndarray, position: np.ndarray, **printed: str) -> PoseReading:
    x, y, z, w = Rotation.from_matrix(rotation).as_quat()
    return PoseReading(
        flange=Frame(tuple(float(v) for v in position), (float(w), float(x), float(y), float(z))),  # type: ignore[arg-type]
        joints_deg=(10.0, -80.0, 95.0, 0.5, 30.0, -45.0),
        live_tool=LiveTool(number=3, frame=Frame((4.0, -7.0, 165.0), (1.0, 0.0, 0.0, 0.0))),
        readings={"$POS_ACT": "{E6POS: X 1.0}", **printed},
    )


class FakeController:
    """Stands for a controller: each session reads `pose` (or fails with `error`); `drift`
    moves the flange along x by that many mm between one read and the next, `turn_deg`
    turns it that many degrees about its own z, its origin staying put."""

    def __init__(self) -> None:
        self.pose = _reading(TOUCHES.R[0], TOUCHES.f[0])
        self.error: Exception | None = None
        self.drift_mm = 0.0
        self.turn_deg = 0.0
        self.read_times: list[float] = []
        self.sessions = 0

    def at(self, index: int) -> None:
        self.pose = _reading(TOUCHES.R[index], TOUCHES.f[index], touch=str(index))

    def connect(self, settings: ControllerSettings) -> Connection:
        self.sessions += 1
        if self.error is not None:
            raise self.error
        return Connection(self)


class Connection(ClosingSession):
    def __init__(self, controller: FakeController) -> None:
        self.controller = controller

    def read_pose(self) -> PoseReading:
        c = self.controller
        c.read_times.append(time.monotonic())
        reading = c.pose
        if c.drift_mm:
            x, y, z = c.pose.flange.position_mm
            moved = Frame((x + c.drift_mm, y, z), c.pose.flange.quaternion)
            c.pose = PoseReading(moved, c.pose.joints_deg, c.pose.live_tool, c.pose.readings)
        if c.turn_deg:
            w, x, y, z = c.pose.flange.quaternion
            turned = Rotation.from_quat([x, y, z, w]) * Rotation.from_euler(
                "z", c.turn_deg, degrees=True
            )
            tx, ty, tz, tw = (float(v) for v in turned.as_quat())
            frame = Frame(c.pose.flange.position_mm, (tw, tx, ty, tz))
            c.pose = PoseReading(frame, c.pose.joints_deg, c.pose.live_tool, c.pose.readings)
        return reading

    def close(self) -> None:
        pass


@pytest.fixture
def controller(monkeypatch: pytest.MonkeyPatch) -> FakeController:
    fake = FakeController()
    monkeypatch.setattr("app.services.controllers.capture.connect", fake.connect)
    return fake


@pytest.fixture
def tool(api: Api) -> dict[str, Any]:
    robot = api.robot("kr16")
    body = {"protocol": "kuka_kvp", "host": "127.0.0.1", "port": 7000, "timeout_s": 1.0}
    put = api.request("PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=body)
    assert put.status_code == 200, put.text
    return api.tool(robot["id"], "torch", slot=3)


def _session(api: Api, tool_id: str, fmt: str = "kuka_abc") -> str:
    body = {"method": "xyz_npoint", "format": fmt, "options": {"touch_noise_mm": 0.01}}
    created = api.post(f"/v1/tools/{tool_id}/sessions", body, scope="calibrate")
    assert created.status_code == 201, created.text
    return str(created.json()["id"])


def _capture(api: Api, sid: str) -> Any:
    return api.post(f"/v1/sessions/{sid}/poses", {"capture": True}, scope="calibrate")


def test_the_pose_is_read_twice_100_ms_apart_and_served_in_the_format_asked(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    api.manual(tool["id"], [4.0, -7.0, 165.0])  # version 1: the frame the robot moves by
    path = f"/v1/robots/{tool['robot_id']}/controller/pose"
    read = api.get(path, scope="calibrate")
    assert read.status_code == 200, read.text
    body = read.json()
    assert len(controller.read_times) == 2
    assert controller.read_times[1] - controller.read_times[0] >= 0.1
    assert controller.sessions == 1  # both reads in one connector session
    matrix = np.asarray(body["pose"])
    np.testing.assert_allclose(matrix[:3, :3], TOUCHES.R[0], atol=1e-12)
    np.testing.assert_allclose(matrix[:3, 3], TOUCHES.f[0], atol=1e-9)
    assert body["still"] is True
    assert body["protocol"] == "kuka_kvp"
    assert body["joints_deg"] == [10.0, -80.0, 95.0, 0.5, 30.0, -45.0]
    assert body["readings"]["$POS_ACT"] == "{E6POS: X 1.0}"
    assert body["live_tool"]["number"] == 3
    assert body["live_tool"]["frame"]["position_mm"] == [4.0, -7.0, 165.0]
    assert body["live_tool"]["matches"] == [{"tool_id": tool["id"], "version": 1, "active": True}]
    abc = api.get(path, scope="calibrate", params={"format": "kuka_abc"}).json()["pose"]
    rotation, position = pose_from_format("kuka_abc", abc)
    np.testing.assert_allclose(rotation, TOUCHES.R[0], atol=1e-12)
    np.testing.assert_allclose(position, TOUCHES.f[0], atol=1e-9)
    joints = api.get(path, scope="calibrate", params={"format": "joints"}).json()["pose"]
    assert joints == [10.0, -80.0, 95.0, 0.5, 30.0, -45.0]
    assert api.get(path, scope="read").status_code == 403  # capturing is calibrate scope


def test_a_moving_robot_is_409_saying_by_how_much_and_the_session_keeps_nothing(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    sid = _session(api, tool["id"])
    assert _capture(api, sid).status_code == 200
    before = api.get(f"/v1/sessions/{sid}").json()
    counts = row_counts(("audit_events", "guided_sessions"))
    controller.drift_mm = 0.02
    moving = _capture(api, sid)
    assert moving.status_code == 409, moving.text
    problem = moving.json()
    assert problem["type"].endswith("/robot-moving")
    assert "0.0200 mm" in problem["detail"]
    assert "nothing was kept" in problem["detail"]
    assert problem["moved_mm"] == pytest.approx(0.02)
    assert api.get(f"/v1/sessions/{sid}").json() == before
    assert row_counts(("audit_events", "guided_sessions")) == counts
    pose = api.get(f"/v1/robots/{tool['robot_id']}/controller/pose", scope="calibrate")
    assert pose.status_code == 409
    controller.drift_mm = 0.009  # within 0.01 mm: still
    assert _capture(api, sid).status_code == 200


def test_a_flange_turning_in_place_is_moving_too(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    """The flange's origin stays put while it turns (a wrist still rotating about the flange
    axis): 0.02 deg moves a TCP 165 mm out by 0.06 mm, so the angle alone refuses it."""
    sid = _session(api, tool["id"])
    counts = row_counts(("audit_events", "guided_sessions"))
    controller.turn_deg = 0.02
    turning = _capture(api, sid)
    assert turning.status_code == 409, turning.text
    problem = turning.json()
    assert problem["type"].endswith("/robot-moving")
    assert problem["moved_mm"] == pytest.approx(0.0, abs=1e-9)
    assert problem["moved_deg"] == pytest.approx(0.02, abs=1e-9)
    assert "0.0200 deg" in problem["detail"]
    assert api.get(f"/v1/sessions/{sid}").json()["n_poses"] == 0
    assert row_counts(("audit_events", "guided_sessions")) == counts
    controller.turn_deg = 0.009  # within 0.01 deg: still
    assert _capture(api, sid).status_code == 200


def test_a_refusing_or_unreachable_controller_is_502_and_nothing_kept(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    sid = _session(api, tool["id"])
    before = api.get(f"/v1/sessions/{sid}").json()
    controller.error = ControllerRefused("external TCP", controller_message="$IPO_MODE #TCP")
    refused = _capture(api, sid)
    assert refused.status_code == 502, refused.text
    assert refused.json()["type"].endswith("/controller-refused")
    assert refused.json()["controller_message"] == "$IPO_MODE #TCP"
    assert "$IPO_MODE #TCP" in refused.json()["detail"]
    controller.error = ControllerUnreachable("connection refused")
    gone = api.get(f"/v1/robots/{tool['robot_id']}/controller/pose", scope="calibrate")
    assert gone.status_code == 502
    assert gone.json()["type"].endswith("/controller-unreachable")
    assert "127.0.0.1:7000" in gone.json()["detail"]
    assert api.get(f"/v1/sessions/{sid}").json() == before


def test_without_a_controller_nothing_is_read(api: Api, controller: FakeController) -> None:
    robot = api.robot("bare")
    tool = api.tool(robot["id"], "t")
    read = api.get(f"/v1/robots/{robot['id']}/controller/pose", scope="calibrate")
    assert read.status_code == 404, read.text  # a read of the controller itself (v1.3)
    assert read.json()["type"].endswith("/no-controller")
    touch = _capture(api, _session(api, tool["id"]))
    assert touch.status_code == 409, touch.text  # a touch that needs one, as a deployment
    assert touch.json()["type"].endswith("/no-controller")
    assert controller.sessions == 0


def test_captured_touches_are_added_as_typed_ones_and_the_calibration_keeps_their_sources(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    captured = _session(api, tool["id"])
    for i in range(7):
        controller.at(i)
        added = _capture(api, captured)
        assert added.status_code == 200, added.text
    poses = api.get(f"/v1/sessions/{captured}").json()["poses"]
    typed_last = poses[0]  # a typed touch among captured ones (the first pose again)
    state = api.post(f"/v1/sessions/{captured}/poses", {"pose": typed_last}, scope="calibrate")
    assert state.status_code == 200, state.text
    touches = state.json()["touches"]
    assert [t["index"] for t in touches] == list(range(8))
    assert [t["source"] for t in touches] == ["controller"] * 7 + ["typed"]
    assert all(t["read_at"] for t in touches[:7])
    assert touches[7]["read_at"] is None
    assert touches[2]["readings"]["touch"] == "2"  # what the controller printed, kept
    # the same poses typed: the same answers, touch by touch
    typed = _session(api, tool["id"])
    for pose in [*poses, typed_last]:
        api.post(f"/v1/sessions/{typed}/poses", {"pose": pose}, scope="calibrate")
    a, b = api.get(f"/v1/sessions/{captured}").json(), api.get(f"/v1/sessions/{typed}").json()
    for field in ("poses", "estimate", "outliers", "next_pose", "done", "messages"):
        assert a[field] == b[field], field
    # a deleted touch takes its source with it
    dropped = api.delete(f"/v1/sessions/{captured}/poses/1", scope="calibrate").json()
    assert [t["readings"]["touch"] for t in dropped["touches"][:3]] == ["0", "2", "3"]
    finished = api.post(f"/v1/sessions/{captured}/finish", {}, scope="calibrate")
    assert finished.status_code == 201, finished.text
    detail = api.get(f"/v1/calibrations/{finished.json()['id']}").json()
    assert [t["source"] for t in detail["touches"]] == ["controller"] * 6 + ["typed"]
    assert detail["touches"][1]["readings"]["touch"] == "2"
    events = api.get("/v1/audit", "admin", params={"action": "session.finish"}).json()["items"]
    assert events[0]["detail"]["sources"][0]["readings"]["$POS_ACT"] == "{E6POS: X 1.0}"
    np.testing.assert_allclose(finished.json()["tcp"]["position_mm"], TOUCHES.t, atol=1e-6)


def test_a_capture_converts_to_the_sessions_format_and_units(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    body = {"method": "xyz_npoint", "format": "ur_rotvec", "units": {"length": "mm"}}
    sid = api.post(f"/v1/tools/{tool['id']}/sessions", body, scope="calibrate").json()["id"]
    controller.at(4)
    pose = _capture(api, sid).json()["poses"][0]
    rotation, position = pose_from_format("ur_rotvec", pose, units={"length": "mm"})
    np.testing.assert_allclose(rotation, TOUCHES.R[4], atol=1e-12)
    np.testing.assert_allclose(position, TOUCHES.f[4], atol=1e-9)


def test_a_finished_session_is_refused_before_the_controller_is_read(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    sid = _session(api, tool["id"])
    for i in range(4):
        controller.at(i)
        _capture(api, sid)
    assert api.post(f"/v1/sessions/{sid}/finish", {}, scope="calibrate").status_code == 201
    sessions = controller.sessions
    assert _capture(api, sid).status_code == 409
    assert controller.sessions == sessions


def test_a_body_with_both_or_neither_is_422(api: Api, tool: dict[str, Any]) -> None:
    sid = _session(api, tool["id"])
    for body in ({}, {"capture": True, "pose": [0, 0, 0, 0, 0, 0]}, {"capture": False}):
        refused = api.post(f"/v1/sessions/{sid}/poses", body, scope="calibrate")
        assert refused.status_code == 422, (body, refused.text)
    check = api.post(
        f"/v1/tools/{tool['id']}/checks",
        {"reference_point_id": "x", "capture": True, "format": "matrix"},
        scope="calibrate",
    )
    assert check.status_code == 422
    assert "leave out format" in check.text


def test_a_captured_check_measures_the_touch_the_controller_reads(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    api.manual(tool["id"], [float(v) for v in TOUCHES.t])
    point = api.post(
        f"/v1/robots/{tool['robot_id']}/reference-points",
        {"name": "pin", "position_mm": [float(v) for v in np.add(TOUCHES.p, [0.3, 0.0, 0.0])]},
        scope="calibrate",
    )
    assert point.status_code == 201, point.text
    controller.at(5)
    body = {"capture": True, "reference_point_id": point.json()["id"]}
    check = api.post(f"/v1/tools/{tool['id']}/checks", body, scope="calibrate")
    assert check.status_code == 201, check.text
    assert check.json()["distance_mm"] == pytest.approx(0.3, abs=1e-6)
    assert len(check.json()["touches"]) == 1
    events = api.get("/v1/audit", "admin", params={"action": "tool.check"}).json()["items"]
    assert events[0]["detail"]["sources"][0]["source"] == "controller"
    assert events[0]["detail"]["sources"][0]["readings"]["touch"] == "5"
    controller.drift_mm = 0.5
    moving = api.post(f"/v1/tools/{tool['id']}/checks", body, scope="calibrate")
    assert moving.status_code == 409
    after = api.get("/v1/audit", "admin", params={"action": "tool.check"}).json()["items"]
    assert len(after) == len(events)  # nothing recorded


def test_a_tools_sessions_are_listed_newest_first_page_by_page(
    api: Api, tool: dict[str, Any]
) -> None:
    ids = [_session(api, tool["id"]) for _ in range(5)]
    other = api.tool(tool["robot_id"], "other")
    _session(api, other["id"])
    seen: list[str] = []
    cursor = None
    while True:
        params: dict[str, Any] = {"limit": 2} | ({"cursor": cursor} if cursor else {})
        page = api.get(f"/v1/tools/{tool['id']}/sessions", params=params)
        assert page.status_code == 200, page.text
        seen += [s["id"] for s in page.json()["items"]]
        cursor = page.json()["next_cursor"]
        if cursor is None:
            break
    assert seen == ids[::-1]
    assert api.get("/v1/tools/nope/sessions").status_code == 404


def test_a_captured_touch_is_refused_as_the_same_pose_typed(
    api: Api, tool: dict[str, Any], controller: FakeController
) -> None:
    """A joints session on a robot without a model: the controller's joint angles are
    refused exactly as the same angles typed, and neither is kept."""
    sid = _session(api, tool["id"], fmt="joints")
    typed = api.post(
        f"/v1/sessions/{sid}/poses",
        {"pose": [10.0, -80.0, 95.0, 0.5, 30.0, -45.0]},
        scope="calibrate",
    )
    captured = _capture(api, sid)
    assert typed.status_code == 422, typed.text
    assert captured.status_code == typed.status_code
    assert captured.json() == typed.json()
    assert api.get(f"/v1/sessions/{sid}").json()["n_poses"] == 0
