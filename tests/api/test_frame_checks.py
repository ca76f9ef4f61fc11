"""A frame's re-check after a move over HTTP (contract v1.4 "After a move: re-register",
issue 49): the stored fiducials touched again by a calibrated pointer (testbed.sim.cell_frames,
noise-free), the shift found, the frame corrected by the lifecycle within max_correction_mm
and left alone beyond it, a robot's every frame and reference point corrected by one check,
each step in the audit trail."""

from __future__ import annotations

import threading
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sqlalchemy import select, update

from app.services.frames.subject import FRAME
from app.services.lifecycle import drift
from app.storage.db import session_scope
from app.storage.models import AuditEvent
from tests.api.controller_rigs import Rig, rig
from tests.api.frame_fiducials import calibrated_frame, cell, touches
from tests.api.test_frame_deployments import FIELDS
from tests.conftest import Api
from tests.controllers.simbase import go_silent
from tests.vendors.test_frame_cuts import CASES


def _frame_pose(api: Api, frame_id: str) -> tuple[np.ndarray, np.ndarray, int]:
    served = api.get(f"/v1/frames/{frame_id}/frame").json()
    q = served["frame"]["quaternion"]
    R = Rotation.from_quat(q, scalar_first=True).as_matrix()
    return R, np.asarray(served["frame"]["position_mm"]), int(served["version"])


def _moved_in_frame(
    R0: np.ndarray, o0: np.ndarray, dt_mm: list[float], deg: float
) -> tuple[np.ndarray, np.ndarray]:
    """The fixture turned by `deg` about its own z axis at its origin and moved by dt (base)."""
    turn = Rotation.from_euler("z", deg, degrees=True).as_matrix()
    return R0 @ turn, o0 + np.asarray(dt_mm)


R_FIXTURE = Rotation.from_euler("zyx", [30.0, 5.0, -3.0], degrees=True).as_matrix()
O_FIXTURE = np.array([700.0, -250.0, 120.0])


def test_a_fixture_moved_1_5_mm_and_0_3_deg_is_corrected_to_within_0_01_mm(api: Api) -> None:
    robot, pointer = cell(api)
    frame = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )
    # 1.5 mm along the way the turn moves fiducial c (500, 300 mm out): 4.55 mm there
    along = R_FIXTURE @ (1.5 * np.array([-300.0, 500.0, 0.0]) / np.hypot(300.0, 500.0))
    R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(along), 0.3)
    body = {**touches(pointer["id"], R1, o1), "correct": "within_limits", "reason": "unbolted"}
    response = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
    assert response.status_code == 201, response.text
    check = response.json()
    assert check["verdict"] == "corrected"
    distances = [d["distance_mm"] for d in check["deviations"]]
    assert max(distances) == pytest.approx(1.5 + np.radians(0.3) * np.hypot(500, 300), abs=1e-3)
    assert check["shift"]["angle_deg"] == pytest.approx(0.3, abs=1e-9)
    assert check["deviations"][2]["words"].startswith("fiducial 'c' moved")
    assert check["correction"]["version"] == 2
    assert check["correction"]["previous_version"] == 1
    assert check["correction"]["deployment"] is None
    assert "not deployed" in check["summary"]
    # the calls it names are this frame's and robot's, not templates
    assert f"GET /v1/frames/{frame['id']}/frame, Accept: text/plain" in check["summary"]
    assert f"PUT /v1/robots/{frame['robot_id']}/controller" in check["summary"]
    assert "{" not in check["summary"]
    R, o, version = _frame_pose(api, frame["id"])
    assert version == 2
    np.testing.assert_allclose(R, R1, atol=1e-9)
    np.testing.assert_allclose(o, o1, atol=1e-6)
    # the same touches checked against the corrected frame: within 0.01 mm at every fiducial
    again = api.post(
        f"/v1/frames/{frame['id']}/checks",
        touches(pointer["id"], R1, o1, seed=7),
        scope="calibrate",
    ).json()
    assert again["verdict"] == "within_tolerance"
    assert max(d["distance_mm"] for d in again["deviations"]) < 0.01
    versions = api.get(f"/v1/frames/{frame['id']}/versions").json()
    assert versions["activations"][-1]["reason"] == "check_correction"
    assert versions["activations"][-1]["reason_text"] == "unbolted"
    events = api.get(f"/v1/audit?frame_id={frame['id']}", scope="admin").json()["items"]
    oldest_first = [e["action"] for e in reversed(events)]
    chain = [a for a in oldest_first if a in ("frame.check", "version.create", "version.activate")]
    assert chain[-4:] == ["frame.check", "version.create", "version.activate", "frame.check"]


def _on_controller(
    api: Api, r: Rig, vendor: str | None = "KUKA", **controller: Any
) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """The cell's robot on the rig's controller, the fixture's frame where it addresses one;
    `controller`: more of the controller's body (a password)."""
    robot, pointer = cell(api, vendor)
    put = api.request(
        "PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=r.controller_body(**controller)
    )
    assert put.status_code == 200, put.text
    frame = calibrated_frame(
        api,
        robot["id"],
        "fixture-a",
        R_FIXTURE,
        O_FIXTURE,
        pointer_id=pointer["id"],
        fields=FIELDS.get(r.protocol, {"slot": 3}),
    )
    return robot, pointer, frame


def test_a_corrected_fixture_is_deployed_verified_once_and_the_controller_holds_it(
    api: Api,
) -> None:
    with rig("kuka_kvp") as r:
        _, pointer, frame = _on_controller(api, r)
        along = R_FIXTURE @ (1.5 * np.array([-300.0, 500.0, 0.0]) / np.hypot(300.0, 500.0))
        R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(along), 0.3)
        body = {**touches(pointer["id"], R1, o1), "correct": "within_limits", "reason": "unbolted"}
        key = {**api.headers("calibrate"), "Idempotency-Key": "moved-1"}
        path = f"/v1/frames/{frame['id']}/checks"
        response = api.post(path, body, scope="calibrate", headers=key)
        assert response.status_code == 201, response.text
        check = response.json()
        assert check["verdict"] == "corrected"
        deployment = check["correction"]["deployment"]
        assert (deployment["frame_id"], deployment["version"], deployment["status"]) == (
            frame["id"],
            2,
            "verified",
        )
        np.testing.assert_allclose(deployment["read_back"]["position_mm"], o1, atol=1e-3)
        assert CASES["kuka_kvp"].held_z(r.sim) == pytest.approx(o1[2], abs=1e-3)
        assert "read back as written (verified)" in check["summary"]
        assert "follows" not in check["summary"]
        again = api.post(path, body, scope="calibrate", headers=key)
        assert again.status_code == 201, again.text
        assert again.headers["idempotent-replayed"] == "true"
        assert again.json() == check
        listed = api.get(f"/v1/frames/{frame['id']}/deployments").json()["items"]
        assert [d["id"] for d in listed] == [deployment["id"]]


def test_a_robot_moved_deploys_each_corrected_frame(api: Api) -> None:
    with rig("kuka_kvp") as r:
        robot, pointer, frame = _on_controller(api, r)
        at_b = (np.eye(3), np.array([300.0, 400.0, 50.0]))
        slot5 = {"slot": 5}
        other = calibrated_frame(
            api, robot["id"], "b", *at_b, pointer_id=pointer["id"], fields=slot5
        )
        dt = [2.0, -1.0, 0.5]
        body = {
            **touches(pointer["id"], R_FIXTURE, O_FIXTURE + np.asarray(dt)),
            "correct": "within_limits",
            "scope": "robot",
        }
        response = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
        assert response.status_code == 201, response.text
        correction = response.json()["correction"]
        assert correction["deployment"]["status"] == "verified"
        [moved] = correction["moved"]
        assert (moved["id"], moved["deployment"]["status"]) == (other["id"], "verified")
        np.testing.assert_allclose(
            moved["deployment"]["read_back"]["position_mm"], [302.0, 399.0, 50.5], atol=1e-3
        )
        for f in (frame, other):
            assert len(api.get(f"/v1/frames/{f['id']}/deployments").json()["items"]) == 1


def test_a_fixture_moved_8_mm_on_a_controller_deploys_nothing(api: Api) -> None:
    with rig("kuka_kvp") as r:
        _, pointer, frame = _on_controller(api, r)
        held = CASES["kuka_kvp"].held_z(r.sim)
        R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, [8.0, 0.0, 0.0], 0.0)
        body = {**touches(pointer["id"], R1, o1), "correct": "within_limits"}
        response = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
        assert response.status_code == 201, response.text
        assert response.json()["verdict"] == "needs_recalibration"
        assert response.json()["correction"] is None
        assert api.get(f"/v1/frames/{frame['id']}/deployments").json()["items"] == []
        assert CASES["kuka_kvp"].held_z(r.sim) == held


def test_a_fixture_moved_8_mm_is_refused_and_nothing_changes(api: Api) -> None:
    robot, pointer = cell(api)
    frame = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )
    R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, [8.0, 0.0, 0.0], 0.0)
    body = {**touches(pointer["id"], R1, o1), "correct": "within_limits"}
    response = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
    assert response.status_code == 201, response.text
    check = response.json()
    assert check["verdict"] == "needs_recalibration"
    assert check["correction"] is None
    assert [d["distance_mm"] for d in check["deviations"]] == pytest.approx([8.0] * 6, abs=1e-9)
    assert "beyond max_correction_mm 5 mm: nothing was changed" in check["summary"]
    assert f"(POST /v1/frames/{frame['id']}/calibrations)" in check["summary"]
    _, o, version = _frame_pose(api, frame["id"])
    assert version == 1
    np.testing.assert_allclose(o, O_FIXTURE, atol=1e-9)
    assert len(api.get(f"/v1/frames/{frame['id']}/versions").json()["items"]) == 1
    events = api.get(f"/v1/audit?frame_id={frame['id']}&action=frame.check", scope="admin").json()[
        "items"
    ]
    assert events[0]["detail"]["within_tolerance"] is False
    assert events[0]["detail"]["verdict"] == "needs_recalibration"  # the fleet's check_failed


def test_a_touch_far_from_the_fiducial_it_names_is_refused_naming_the_one_it_is_near(
    api: Api,
) -> None:
    robot, pointer = cell(api)
    frame = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )
    body = touches(pointer["id"], R_FIXTURE, O_FIXTURE, names=["a", "b", "c", "d"])
    body["touches"][1]["fiducial"] = "c"  # b touched, c named
    body["touches"][2]["fiducial"] = "b"
    response = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["errors"][0]["loc"] == ["body", "touches", 1, "fiducial"]
    assert "from fiducial 'b'" in problem["detail"]
    assert len(api.get(f"/v1/frames/{frame['id']}/versions").json()["items"]) == 1


def test_a_robot_moved_is_corrected_at_every_frame_and_reference_point_by_one_check(
    api: Api,
) -> None:
    robot, pointer = cell(api)
    poses = {
        "fixture-a": (R_FIXTURE, O_FIXTURE),
        "fixture-b": (np.eye(3), np.array([300.0, 400.0, 50.0])),
        "table": (
            Rotation.from_euler("x", 180, degrees=True).as_matrix(),
            np.array([0, -600.0, 0]),
        ),
    }
    frames = {
        n: calibrated_frame(
            api, robot["id"], n, R, o, max_correction_mm=10.0, pointer_id=pointer["id"]
        )
        for n, (R, o) in poses.items()
    }
    point = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "pin", "position_mm": [600.0, 100.0, 20.0]},
    )
    assert point.status_code == 201, point.text
    dR = Rotation.from_rotvec(np.radians(0.2) * np.array([0.0, 0.6, 0.8])).as_matrix()
    dt = np.array([2.0, -1.0, 0.5])
    R0, o0 = poses["fixture-a"]
    body = {
        **touches(pointer["id"], dR @ R0, dR @ o0 + dt),
        "correct": "within_limits",
        "scope": "robot",
        "reason": "robot re-mounted after maintenance",
    }
    response = api.post(f"/v1/frames/{frames['fixture-a']['id']}/checks", body, scope="calibrate")
    assert response.status_code == 201, response.text
    check = response.json()
    assert check["verdict"] == "corrected"
    moved = check["correction"]["moved"]
    assert sorted((m["kind"], m["name"]) for m in moved) == [
        ("frame", "fixture-b"),
        ("frame", "table"),
        ("reference_point", "pin"),
    ]
    assert "2 other frames and 1 reference point corrected by the same shift" in check["summary"]
    np.testing.assert_allclose(check["shift"]["position_mm"], dt - np.zeros(3), atol=1e-6)
    assert check["shift"]["angle_deg"] == pytest.approx(0.2, abs=1e-9)
    for name, (R, o) in poses.items():
        got_R, got_o, version = _frame_pose(api, frames[name]["id"])
        assert version == 2, name
        np.testing.assert_allclose(got_R, dR @ R, atol=1e-9)
        np.testing.assert_allclose(got_o, dR @ o + dt, atol=1e-6)
        activations = api.get(f"/v1/frames/{frames[name]['id']}/versions").json()["activations"]
        assert activations[-1]["reason"] == "check_correction"
        assert activations[-1]["reason_text"] == "robot re-mounted after maintenance"
    pin = api.get(f"/v1/robots/{robot['id']}/reference-points").json()["items"][0]
    np.testing.assert_allclose(pin["position_mm"], dR @ [600.0, 100.0, 20.0] + dt, atol=1e-6)
    moves = api.get("/v1/audit?action=reference_point.move", scope="admin").json()["items"]
    assert moves[0]["detail"]["check_id"] == check["id"]


def test_a_shift_that_differs_from_another_frames_within_the_hour_is_said(api: Api) -> None:
    robot, pointer = cell(api)
    a = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )
    b = calibrated_frame(
        api,
        robot["id"],
        "fixture-b",
        np.eye(3),
        np.array([300.0, 400.0, 50]),
        pointer_id=pointer["id"],
    )
    R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, [2.0, 0.0, 0.0], 0.0)
    first = api.post(
        f"/v1/frames/{a['id']}/checks", touches(pointer["id"], R1, o1), scope="calibrate"
    )
    assert first.json()["differs_from"] == []
    second = api.post(
        f"/v1/frames/{b['id']}/checks",
        touches(pointer["id"], np.eye(3), np.array([300.0, 400.0, 50])),
        scope="calibrate",
    ).json()
    assert second["differs_from"] == [a["id"]]
    assert "one fixture moved, not the robot (not averaged)" in second["summary"]


def test_a_repeated_key_sent_concurrently_makes_one_version(api: Api) -> None:
    robot, pointer = cell(api)
    frame = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )
    R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, [1.0, 0.5, 0.0], 0.1)
    body = {**touches(pointer["id"], R1, o1), "correct": "within_limits"}
    answers: list[Any] = []

    def send() -> None:
        answers.append(
            api.post(
                f"/v1/frames/{frame['id']}/checks",
                body,
                scope="calibrate",
                headers={**api.headers("calibrate"), "Idempotency-Key": "move-1"},
            )
        )

    threads = [threading.Thread(target=send) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(a.status_code for a in answers) == [201, 201, 201]
    assert sorted(a.headers.get("idempotent-replayed", "") for a in answers) == ["", "true", "true"]
    assert len({a.json()["id"] for a in answers}) == 1
    assert len(api.get(f"/v1/frames/{frame['id']}/versions").json()["items"]) == 2


def test_the_frames_drift_trend_reads_its_checks(api: Api) -> None:
    """A frame's checks are its drift trend's check series (FRAME.check_action): three checks
    10 days apart, the fixture creeping 0.1 mm each time, give a trend of three points."""
    robot, pointer = cell(api)
    frame = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )
    for step in (1, 2, 3):
        crept = O_FIXTURE + R_FIXTURE @ np.array([0.1 * step, 0.0, 0.0])
        done = api.post(
            f"/v1/frames/{frame['id']}/checks",
            touches(pointer["id"], R_FIXTURE, crept, seed=step),
            scope="calibrate",
        )
        assert done.json()["verdict"] == "within_tolerance", done.text
    now = datetime.now(UTC)
    with session_scope(write=True) as session:
        ids = session.scalars(
            select(AuditEvent.id)
            .where(AuditEvent.frame_id == frame["id"], AuditEvent.action == "frame.check")
            .order_by(AuditEvent.id)
        ).all()
        for age, event_id in zip((20, 10, 0), ids, strict=True):
            session.execute(
                update(AuditEvent)
                .where(AuditEvent.id == event_id)
                .values(at=now - timedelta(days=age))
            )
    with session_scope(write=False) as session:
        trend = drift.compute_drift(
            session, FRAME, subject_id=frame["id"], active_version=1, check_mm=0.5
        )
    checks = trend.drift["checks"]
    assert isinstance(checks, dict)
    assert checks["n"] == 3
    assert checks["speed_mm_per_month"] == pytest.approx(0.3, rel=0.05)  # 0.1 mm / 10 days


def test_the_fleet_says_check_failed_and_frequent_corrections_of_a_frame(api: Api) -> None:
    """A frame moved beyond max_correction_mm is the fleet's check_failed until corrected; a
    frame corrected by re-checks more than TCPCAL_CORRECTIONS_ALERT (3) times in 30 days is
    its frequent_corrections, each count the lifecycle's check_correction activations."""
    robot, pointer = cell(api)
    frame = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )

    def attention() -> list[str]:
        rows = api.get("/v1/frames").json()["items"]
        return list(next(r for r in rows if r["id"] == frame["id"])["attention"])

    far = O_FIXTURE + np.array([8.0, 0.0, 0.0])
    body = {**touches(pointer["id"], R_FIXTURE, far), "correct": "within_limits"}
    refused = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
    assert refused.json()["verdict"] == "needs_recalibration"
    assert "check_failed" in attention()
    origin = O_FIXTURE
    for step in range(4):
        origin = origin + np.array([1.0, 0.0, 0.0])
        body = {**touches(pointer["id"], R_FIXTURE, origin, seed=step), "correct": "within_limits"}
        done = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
        assert done.json()["verdict"] == "corrected", done.text
        assert "check_failed" not in attention()
        assert ("frequent_corrections" in attention()) == (step == 3)


@pytest.mark.parametrize("protocol", ["yaskawa_hses", "ur_rtde"])
def test_a_correction_on_a_controller_that_writes_no_frame_is_active_and_says_load_the_file(
    api: Api, protocol: str
) -> None:
    """No deployment is attempted (it could only be 501 /no-frame-writer): the new version
    is stored and active, and the answer says no deployment was made, why, and the file."""
    with rig(protocol) as r:
        _, pointer, frame = _on_controller(api, r, vendor=None)
        along = R_FIXTURE @ (1.5 * np.array([-300.0, 500.0, 0.0]) / np.hypot(300.0, 500.0))
        R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(along), 0.3)
        body = {**touches(pointer["id"], R1, o1), "correct": "within_limits"}
        response = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
        assert response.status_code == 201, response.text
        check = response.json()
        assert check["verdict"] == "corrected"
        assert check["correction"]["version"] == 2
        assert check["correction"]["deployment"] is None
        said = check["summary"]
        assert "no deployment was made" in said, said
        assert "failed" not in said, said
        assert "by hand" in said, said
        file = {"yaskawa_hses": "UFRAME.CND", "ur_rtde": "URScript file"}[protocol]
        assert file in said, said
        assert _frame_pose(api, frame["id"])[2] == 2
        assert api.get(f"/v1/frames/{frame['id']}/deployments").json()["items"] == []


def test_a_failed_deployment_of_a_correction_flags_the_frames_controller_state(
    api: Api,
) -> None:
    """As a tool's re-check does: the controller stopped answering after the write, so the
    frame's controller state is unreachable at the new version."""
    with rig("kuka_kvp") as r:
        robot, pointer, frame = _on_controller(api, r)
        along = R_FIXTURE @ (1.5 * np.array([-300.0, 500.0, 0.0]) / np.hypot(300.0, 500.0))
        R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(along), 0.3)
        body = {**touches(pointer["id"], R1, o1), "correct": "within_limits"}
        r.sim.fault = go_silent("after", CASES["kuka_kvp"].write)
        response = api.post(f"/v1/frames/{frame['id']}/checks", body, scope="calibrate")
        assert response.status_code == 201, response.text
        check = response.json()
        assert check["correction"]["deployment"]["status"] == "unverified"
        assert "its deployment failed" in check["summary"]
        [row] = api.get(f"/v1/frames?robot_id={robot['id']}").json()["items"]
        state = row["controller"]
        assert state is not None, row
        assert (state["state"], state["version"], state["target"]) == (
            "unreachable",
            2,
            "BASE_DATA[3]",
        ), state
