"""Deploy a tool's active TCP to each controller's simulator, read back, reconcile."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sqlalchemy import text

from app.storage.db import get_engine
from tests.api.controller_rigs import LIVE_PROTOCOLS, PROTOCOLS, SLOT, TIMEOUT_S, Rig, rig
from tests.api.controller_rigs import secret_key as secret_key  # autouse: ABB passwords
from tests.conftest import Api
from tests.controllers.helpers import angle_between_deg
from tests.controllers.simbase import go_silent

#: Protocols whose robot moves by one live TCP (contract v1.3 deployment scope "live").
LIVE_SCOPE = LIVE_PROTOCOLS
ACTIVE_POSITION = [12.5, -3.25, 187.125]
ACTIVE_Q = [
    float(v) for v in np.roll(Rotation.from_euler("ZYX", [30, -20, 10], degrees=True).as_quat(), 1)
]
PREVIOUS_POSITION = [1.0, 2.0, 150.0]
PREVIOUS_Q = [
    float(v) for v in np.roll(Rotation.from_euler("ZYX", [5, 0, 0], degrees=True).as_quat(), 1)
]


@pytest.fixture(params=PROTOCOLS)
def protocol_rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    with rig(request.param) as r:
        yield r


def _setup(
    api: Api, r: Rig, *, calibrated: bool = True, timeout_s: float = TIMEOUT_S, **tool_fields: Any
) -> dict[str, Any]:
    robot = api.robot()
    body = r.controller_body(timeout_s=timeout_s)
    put = api.request("PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=body)
    assert put.status_code == 200, put.text
    fields = {**r.tool_fields, **tool_fields}
    tool = api.tool(robot["id"], load={"mass_kg": 2.5, "cog_mm": [0, 0, 80]}, **fields)
    if calibrated:
        body = {"method": "manual", "tcp": {"position_mm": ACTIVE_POSITION, "quaternion": ACTIVE_Q}}
        done = api.post(f"/v1/tools/{tool['id']}/calibrations", body, scope="calibrate")
        assert done.status_code == 201, done.text
    return {"robot": robot, "tool": tool}


def _deploy(api: Api, tool_id: str, body: dict[str, Any] | None = None, /, **headers: str) -> Any:
    return api.post(
        f"/v1/tools/{tool_id}/deployments", body or {}, scope="calibrate", headers=headers
    )


def _deployments(api: Api, tool_id: str) -> list[dict[str, Any]]:
    r = api.get(f"/v1/tools/{tool_id}/deployments")
    assert r.status_code == 200, r.text
    return list(r.json()["items"])


def _audit_actions(tool_id: str) -> list[str]:
    with get_engine().connect() as conn:
        rows = conn.execute(
            text("SELECT action FROM audit_events WHERE tool_id = :t ORDER BY id"), {"t": tool_id}
        )
        return [r.action for r in rows]


def test_deploy_writes_the_active_tcp_reads_it_back_and_records_previous(
    api: Api, protocol_rig: Rig
) -> None:
    r = protocol_rig
    r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
    previous_held = r.held()
    ids = _setup(api, r)
    tool_id = ids["tool"]["id"]
    done = _deploy(api, tool_id)
    assert done.status_code == 201, done.text
    dep = done.json()
    assert dep["status"] == "verified"
    assert dep["version"] == 1
    assert dep["protocol"] == r.protocol
    assert dep["deviation_mm"] <= 0.001
    assert dep["deviation_deg"] <= 0.001
    # the controller holds the active TCP in its own convention
    r.assert_holds(ACTIVE_POSITION, ACTIVE_Q)
    # `previous` is what it held before
    np.testing.assert_allclose(dep["previous"]["position_mm"], previous_held[0], atol=1e-4)
    assert _angle(dep["previous"]["quaternion"], previous_held[1]) < 1e-3
    np.testing.assert_allclose(dep["read_back"]["position_mm"], ACTIVE_POSITION, atol=1e-3)
    listed = _deployments(api, tool_id)
    assert [d["id"] for d in listed] == [dep["id"]]
    assert "tool.deploy" in _audit_actions(tool_id)
    # a second deployment is listed first; its previous is the first's read-back
    again = _deploy(api, tool_id).json()
    assert [d["id"] for d in _deployments(api, tool_id)] == [again["id"], dep["id"]]
    np.testing.assert_allclose(again["previous"]["position_mm"], ACTIVE_POSITION, atol=1e-3)
    row = api.get("/v1/tools", params={"robot_id": ids["robot"]["id"]}).json()["items"][0]
    assert row["controller"]["state"] == "in_sync"
    metrics = api.get("/metrics").text
    assert f'tcpcal_deployments_total{{protocol="{r.protocol}",status="verified"}}' in metrics
    # the connection removed: the fleet no longer claims a state
    assert api.delete(f"/v1/robots/{ids['robot']['id']}/controller").status_code == 204
    row = api.get("/v1/tools", params={"robot_id": ids["robot"]["id"]}).json()["items"][0]
    assert row["controller"] is None
    assert len(_deployments(api, tool_id)) == 2  # the history stays


def _angle(q1: list[float], q2: list[float]) -> float:
    return angle_between_deg(tuple(q1), tuple(q2))


def test_reconcile_finds_a_frame_changed_behind_tcpcals_back(api: Api, protocol_rig: Rig) -> None:
    r = protocol_rig
    ids = _setup(api, r)
    tool_id, robot_id = ids["tool"]["id"], ids["robot"]["id"]
    assert _deploy(api, tool_id).status_code == 201
    first = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    assert first.status_code == 200, first.text
    assert first.json()["state"] == "in_sync"
    assert first.json()["tools"][0]["state"] == "in_sync"
    moved = [ACTIVE_POSITION[0] + 0.5, ACTIVE_POSITION[1], ACTIVE_POSITION[2]]
    r.set_behind_back(moved, ACTIVE_Q)
    drifted = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read").json()
    assert drifted["state"] == "drifted"
    t = drifted["tools"][0]
    assert t["state"] == "drifted"
    assert t["tool_id"] == tool_id
    np.testing.assert_allclose(t["controller"]["position_mm"], moved, atol=1e-3)
    np.testing.assert_allclose(t["active"]["position_mm"], ACTIVE_POSITION, atol=1e-9)
    assert t["active"]["version"] == 1
    assert t["deviation_mm"] == pytest.approx(0.5, abs=1e-3)
    since = t["since"]
    again = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read").json()["tools"][0]
    assert again["state"] == "drifted"
    assert again["since"] == since
    assert _audit_actions(tool_id).count("controller.drifted") == 1
    [event] = api.get(
        "/v1/audit", params={"tool_id": tool_id, "action": "controller.drifted"}, scope="admin"
    ).json()["items"]
    assert (event["version"], event["detail"]["version"]) == (1, 1)  # the version it holds
    row = api.get("/v1/tools", params={"robot_id": robot_id}).json()["items"][0]
    assert row["controller"]["state"] == "drifted"
    # what the robot moves by (issue 39: a simulator's own live tool) is tests/api/test_fleet_live
    assert [c for c in row["attention"] if not c.startswith("moving_by_")] == ["controller_drifted"]
    flagged = api.get("/v1/tools", params={"attention": "true"}).json()["items"]
    assert [t["id"] for t in flagged] == [tool_id]
    assert row["controller"]["deviation_mm"] == pytest.approx(0.5, abs=1e-3)
    csv = api.get("/v1/tools", headers={"Accept": "text/csv"}).text
    assert ",drifted," in csv
    metrics = api.get("/metrics").text
    assert 'tcpcal_controller_state_changes_total{state="drifted"}' in metrics
    # put back: in sync again, one more event
    r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)
    back = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read").json()
    assert back["state"] == "in_sync"
    assert _audit_actions(tool_id).count("controller.in_sync") == 2  # deploy, then back


def test_a_stopped_controller_is_502_unreachable_within_the_timeout_and_recorded(
    api: Api, protocol_rig: Rig
) -> None:
    r = protocol_rig
    ids = _setup(api, r)
    tool_id = ids["tool"]["id"]
    before = api.get(f"/v1/tools/{tool_id}")
    r.sim.stop()
    started = time.monotonic()
    failed = _deploy(api, tool_id)
    elapsed = time.monotonic() - started
    assert failed.status_code == 502, failed.text
    assert failed.json()["type"].endswith("/controller-unreachable")
    assert elapsed < TIMEOUT_S + 1
    listed = _deployments(api, tool_id)
    assert [d["id"] for d in listed] == [failed.json()["deployment_id"]]
    assert listed[0]["status"] == "not_written"
    assert listed[0]["error"]["type"] == "controller-unreachable"
    after = api.get(f"/v1/tools/{tool_id}")
    assert after.headers["etag"] == before.headers["etag"]  # nothing else changed
    recon = api.post(f"/v1/robots/{ids['robot']['id']}/reconcile", scope="read").json()
    assert recon["state"] == "unreachable"
    # one live TCP (no deployment reached it) too: not reached, the tool is unreachable
    assert recon["tools"][0]["state"] == "unreachable"
    assert recon["tools"][0]["error"]
    row = api.get("/v1/tools", params={"robot_id": ids["robot"]["id"]}).json()["items"][0]
    assert row["attention"] == ["controller_unreachable"]


def test_a_stalled_controller_is_502_within_the_timeout(api: Api, protocol_rig: Rig) -> None:
    r = protocol_rig
    # A short timeout: the deployment waits it out, and a test of each protocol on each backend
    # waited a whole second for nothing.
    timeout_s = 0.3
    ids = _setup(api, r, timeout_s=timeout_s)
    r.sim.stalled = True
    started = time.monotonic()
    failed = _deploy(api, ids["tool"]["id"])
    assert failed.status_code == 502, failed.text
    assert failed.json()["type"].endswith("/controller-unreachable")
    assert timeout_s <= time.monotonic() - started < timeout_s + 1


def test_idempotency_key_replays_a_verified_deployment(api: Api, protocol_rig: Rig) -> None:
    ids = _setup(api, protocol_rig)
    tool_id = ids["tool"]["id"]
    first = _deploy(api, tool_id, **{"Idempotency-Key": "deploy-1"})
    second = _deploy(api, tool_id, **{"Idempotency-Key": "deploy-1"})
    assert first.status_code == second.status_code == 201
    assert second.headers.get("idempotent-replayed") == "true"
    assert second.json() == first.json()
    assert len(_deployments(api, tool_id)) == 1
    bodiless = api.request("POST", f"/v1/tools/{tool_id}/deployments", "calibrate")
    assert bodiless.status_code == 201, bodiless.text  # no body is the same as {}
    other = api.post(
        f"/v1/tools/{tool_id}/deployments",
        {"x": 1},
        scope="calibrate",
        headers={"Idempotency-Key": "deploy-1"},
    )
    assert other.status_code == 422  # the body is {} and nothing else


def test_no_active_version_is_409_and_nothing_recorded(api: Api, protocol_rig: Rig) -> None:
    ids = _setup(api, protocol_rig, calibrated=False)
    r = _deploy(api, ids["tool"]["id"])
    assert r.status_code == 409
    assert r.json()["type"].endswith("/no-active-version")
    assert _deployments(api, ids["tool"]["id"]) == []


def test_a_tool_without_its_slot_is_422_naming_it(api: Api) -> None:
    with rig("kuka_kvp") as r:
        ids = _setup(api, r, slot=None)
        done = _deploy(api, ids["tool"]["id"])
        assert done.status_code == 422, done.text
        assert done.json()["field"] == "slot"
        assert "1-16" in done.json()["detail"]
        assert _deployments(api, ids["tool"]["id"]) == []
        # reconcile leaves it out and says why
        recon = api.post(f"/v1/robots/{ids['robot']['id']}/reconcile", scope="read").json()
        assert recon["tools"] == []
        assert recon["not_addressable"][0]["tool_id"] == ids["tool"]["id"]


def test_an_abb_tool_without_its_symbol_is_422_naming_controller_symbol(api: Api) -> None:
    robot = api.robot()
    put = api.request(
        "PUT",
        f"/v1/robots/{robot['id']}/controller",
        "admin",
        json={"protocol": "abb_rws1", "host": "127.0.0.1", "port": 9},
    )
    assert put.status_code == 200
    tool = api.tool(robot["id"])
    api.manual(tool["id"], [0, 0, 100])
    done = _deploy(api, tool["id"])
    assert done.status_code == 422
    assert done.json()["field"] == "controller_symbol"
    assert _deployments(api, tool["id"]) == []


def test_a_robot_without_a_controller_is_409(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"], slot=1)
    api.manual(tool["id"], [0, 0, 100])
    done = _deploy(api, tool["id"])
    assert done.status_code == 409
    assert done.json()["type"].endswith("/no-controller")
    recon = api.post(f"/v1/robots/{robot['id']}/reconcile", scope="read")
    assert recon.status_code == 409


WRONG_PASSWORD = "not-the-Robotics-password-4b1d"


@pytest.mark.parametrize("protocol", ["abb_rws1", "abb_rws2"])
def test_a_wrong_password_is_502_refused_in_the_controllers_words(
    api: Api, protocol: str, capfd: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    with rig(protocol) as r:
        ids = _setup(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        put = api.request(
            "PUT",
            f"/v1/robots/{robot_id}/controller",
            "admin",
            json=r.controller_body(password=WRONG_PASSWORD),
        )
        assert put.status_code == 200
        refused = _deploy(api, tool_id)
        assert refused.status_code == 502, refused.text
        problem = refused.json()
        assert problem["type"].endswith("/controller-refused")
        assert problem["controller_message"]  # the controller's own words
        assert problem["controller_message"] in problem["detail"]
        listed = _deployments(api, tool_id)
        assert listed[0]["id"] == problem["deployment_id"]
        assert listed[0]["status"] == "not_written"
        assert listed[0]["error"]["controller_message"] == problem["controller_message"]
        recon = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
        assert recon.json()["state"] == "unreachable"
        captured = capfd.readouterr()
        for seen in (
            refused.text,
            put.text,
            recon.text,
            str(listed),
            captured.err,
            captured.out,
            caplog.text,
        ):
            assert WRONG_PASSWORD not in seen


def test_a_value_the_controller_cannot_hold_is_502_mismatch_and_recorded(api: Api) -> None:
    """A KRL REAL is a 32-bit float: 40 000.0015 mm is held as 40 000.0 mm, 0.0015 mm off."""
    with rig("kuka_kvp") as r:
        robot = api.robot()
        api.request(
            "PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=r.controller_body()
        )
        tool = api.tool(robot["id"], slot=3)
        api.manual(tool["id"], [40000.0015, 0.0, 0.0])
        refused = _deploy(api, tool["id"])
        assert refused.status_code == 502, refused.text
        assert refused.json()["type"].endswith("/controller-mismatch")
        listed = _deployments(api, tool["id"])
        assert listed[0]["id"] == refused.json()["deployment_id"]
        assert listed[0]["status"] == "mismatch"
        assert listed[0]["deviation_mm"] == pytest.approx(0.0015, abs=2e-4)
        assert listed[0]["read_back"]["position_mm"][0] == pytest.approx(40000.0, abs=1e-6)
        row = api.get("/v1/tools", params={"robot_id": robot["id"]}).json()["items"][0]
        assert row["controller"] is None  # a mismatch does not claim the controller in sync


def test_a_symbol_the_controller_does_not_know_is_refused_in_its_words(api: Api) -> None:
    """Deploying to a missing PERS tooldata is refused (nothing written); reconcile reads the
    robot's other tools all the same and says which one it could not read, and why."""
    with rig("abb_rws1") as r:
        ids = _setup(api, r)
        robot_id = ids["robot"]["id"]
        missing = api.tool(robot_id, name="glue", controller_symbol="T_ROB1/user/tGlue")
        api.manual(missing["id"], [0.0, 0.0, 120.0])
        refused = _deploy(api, missing["id"])
        assert refused.status_code == 502, refused.text
        assert refused.json()["type"].endswith("/controller-refused")
        assert refused.json()["controller_message"]
        assert "T_ROB1/user/tGlue" not in r.sim.symbols  # nothing was created
        assert _deploy(api, ids["tool"]["id"]).status_code == 201
        recon = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read").json()
        states = {t["tool_id"]: t for t in recon["tools"]}
        assert states[ids["tool"]["id"]]["state"] == "in_sync"
        assert states[missing["id"]]["state"] == "unreachable"
        assert states[missing["id"]]["error"].startswith("refused: ")
        assert recon["state"] == "unreachable"  # the worst of its tools'


#: The write as each simulator names it.
WRITE_REQUEST = {
    "kuka_kvp": f"write $TOOL_DATA[{SLOT}]",
    "fanuc_rmi": "FRC_WriteUToolData",
    "abb_rws1": "POST /rw/rapid/symbol/data/RAPID/T_ROB1/user/tTorch",
    "abb_rws2": "POST /rw/rapid/symbol/RAPID/T_ROB1/user/tTorch/data",
    # the controller applies a loaded TOOL.CND at its last block
    "yaskawa_hses": "load TOOL.CND last block",
    "ur_rtde": "script",  # the set_tcp program on the secondary interface
    "techman": "ChangeTCP",
}
#: The last request before the write, and which time it comes in a deployment. KUKA reads
#: $LOAD_DATA for `previous` and again for the load members it keeps; ABB reads the tooldata
#: for `previous` and again for the robhold and load it keeps. FANUC RMI sends nothing
#: between its read of `previous` and the write, so that controller stops at the read (so does
#: Techman's: a tool with a load writes it, and reads no TCP_Mass to keep); UR asks nothing
#: after RTDE starts its data, so that one stops at the start.
BEFORE_WRITE = {
    "kuka_kvp": (f"read $LOAD_DATA[{SLOT}]", 2),
    "fanuc_rmi": ("FRC_ReadUToolData", 1),
    "abb_rws1": ("GET /rw/rapid/symbol/data/RAPID/T_ROB1/user/tTorch", 2),
    "abb_rws2": ("GET /rw/rapid/symbol/RAPID/T_ROB1/user/tTorch/data", 2),
    # the load's request: no data has left yet (the file goes in the blocks after it)
    "yaskawa_hses": ("load TOOL.CND", 1),
    "ur_rtde": ("RTDE_CONTROL_PACKAGE_START", 1),
    "techman": ("TMSVR 12", 1),
}
NOT_CONFIRMED = (
    "written, not confirmed: the controller may hold v1 or what it held before; "
    "the next reconcile round will tell"
)
NOTHING_WRITTEN = "nothing was written: the controller still holds what it held"


def _audit(api: Api, tool_id: str, action: str) -> list[dict[str, Any]]:
    found = api.get("/v1/audit", params={"tool_id": tool_id, "action": action}, scope="admin")
    assert found.status_code == 200, found.text
    return list(found.json()["items"])


def _failed_deploy(api: Api, tool_id: str, status: str) -> dict[str, Any]:
    """A deployment that fails with `status` (recorded so, and in its audit event): its 502
    problem, whose detail the record repeats (the tests check its `deployment_status`)."""
    failed = _deploy(api, tool_id)
    assert failed.status_code == 502, failed.text
    problem: dict[str, Any] = failed.json()
    [dep] = _deployments(api, tool_id)
    assert dep["id"] == problem["deployment_id"]
    assert dep["status"] == status
    assert dep["error"]["detail"] == problem["detail"]
    [event] = _audit(api, tool_id, "tool.deploy")
    assert event["detail"]["status"] == status
    assert event["detail"]["error"]["detail"] == problem["detail"]
    return problem


def test_a_controller_silent_right_after_the_write_is_unverified_until_reconcile_settles_it(
    api: Api, protocol_rig: Rig
) -> None:
    """The controller applies the write and stops answering: it holds the new TCP, and the
    deployment says it may (`unverified`, `previous` kept), never "nothing was written"."""
    r = protocol_rig
    r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
    ids = _setup(api, r)
    tool_id, robot_id = ids["tool"]["id"], ids["robot"]["id"]
    r.sim.fault = go_silent("after", WRITE_REQUEST[r.protocol])
    problem = _failed_deploy(api, tool_id, "unverified")
    r.assert_holds(ACTIVE_POSITION, ACTIVE_Q)  # the controller took the new TCP
    [dep] = _deployments(api, tool_id)
    np.testing.assert_allclose(dep["previous"]["position_mm"], PREVIOUS_POSITION, atol=1e-3)
    assert _angle(dep["previous"]["quaternion"], PREVIOUS_Q) < 1e-3
    assert problem["type"].endswith("/controller-unreachable")
    assert problem["deployment_status"] == "unverified"  # RFC 9457 keeps `status` for HTTP
    assert NOT_CONFIRMED in problem["detail"]
    assert "nothing was written" not in problem["detail"]
    assert dep["settled"] is None
    # the controller back: the next round records what it holds, once
    r.sim.stalled = False
    recon = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    assert recon.json()["tools"][0]["state"] == "in_sync", recon.text
    [dep] = _deployments(api, tool_id)
    assert dep["status"] == "unverified"  # what was known then; `settled` says what came of it
    assert dep["settled"]["holds"] == "written"
    np.testing.assert_allclose(dep["settled"]["frame"]["position_mm"], ACTIVE_POSITION, atol=1e-3)
    assert dep["settled"]["at"] == recon.json()["checked_at"]
    api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    [event] = _audit(api, tool_id, "deployment.settled")
    assert (event["resource_id"], event["version"]) == (dep["id"], 1)
    assert event["detail"]["holds"] == "written"


def test_a_controller_silent_before_the_write_is_not_written_and_keeps_its_frame(
    api: Api, protocol_rig: Rig
) -> None:
    r = protocol_rig
    r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
    ids = _setup(api, r)
    tool_id, robot_id = ids["tool"]["id"], ids["robot"]["id"]
    request, nth = BEFORE_WRITE[r.protocol]
    r.sim.fault = go_silent("before", request, nth=nth)
    problem = _failed_deploy(api, tool_id, "not_written")
    r.assert_holds(PREVIOUS_POSITION, PREVIOUS_Q)  # untouched
    [dep] = _deployments(api, tool_id)
    if r.protocol in ("fanuc_rmi", "ur_rtde", "techman"):
        assert dep["previous"] is None  # it stopped at or before that read
    else:
        np.testing.assert_allclose(dep["previous"]["position_mm"], PREVIOUS_POSITION, atol=1e-3)
    assert problem["type"].endswith("/controller-unreachable")
    assert problem["deployment_status"] == "not_written"
    assert NOTHING_WRITTEN in problem["detail"]
    r.sim.stalled = False
    recon = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    # a live TCP judges the tool last deployed to it, and a not_written one does not count
    kept = "not_live" if r.protocol in LIVE_SCOPE else "drifted"
    assert recon.json()["tools"][0]["state"] == kept, recon.text
    assert _deployments(api, tool_id)[0]["settled"] is None  # nothing to settle
    assert _audit(api, tool_id, "deployment.settled") == []


def test_a_write_sent_and_never_applied_is_unverified_and_settled_as_the_previous_frame(
    api: Api, protocol_rig: Rig
) -> None:
    """The write left and the controller stopped before applying it: tcpcal cannot know,
    so it says `unverified`; the next round finds the frame from before."""
    r = protocol_rig
    r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
    ids = _setup(api, r)
    tool_id, robot_id = ids["tool"]["id"], ids["robot"]["id"]
    r.sim.fault = go_silent("before", WRITE_REQUEST[r.protocol])
    problem = _failed_deploy(api, tool_id, "unverified")
    assert problem["deployment_status"] == "unverified"
    assert NOT_CONFIRMED in problem["detail"]
    r.assert_holds(PREVIOUS_POSITION, PREVIOUS_Q)
    r.sim.stalled = False
    recon = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    assert recon.json()["tools"][0]["state"] == "drifted", recon.text
    [dep] = _deployments(api, tool_id)
    assert dep["settled"]["holds"] == "previous"
    np.testing.assert_allclose(dep["settled"]["frame"]["position_mm"], PREVIOUS_POSITION, atol=1e-3)
    [event] = _audit(api, tool_id, "deployment.settled")
    assert event["detail"]["holds"] == "previous"


def test_an_unverified_deployment_is_settled_as_other_when_the_pendant_changed_it(
    api: Api,
) -> None:
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        tool_id, robot_id = ids["tool"]["id"], ids["robot"]["id"]
        r.sim.fault = go_silent("after", WRITE_REQUEST[r.protocol])
        _failed_deploy(api, tool_id, "unverified")
        r.sim.stalled = False
        elsewhere = [40.0, 0.0, 100.0]
        r.set_behind_back(elsewhere, PREVIOUS_Q)
        api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
        settled = _deployments(api, tool_id)[0]["settled"]
        assert settled["holds"] == "other"
        np.testing.assert_allclose(settled["frame"]["position_mm"], elsewhere, atol=1e-3)


def test_a_superseded_unverified_deployment_is_left_unsettled(api: Api) -> None:
    """What the controller holds now says nothing about an attempt a later one followed."""
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        tool_id, robot_id = ids["tool"]["id"], ids["robot"]["id"]
        r.sim.fault = go_silent("after", WRITE_REQUEST[r.protocol])
        _failed_deploy(api, tool_id, "unverified")
        r.sim.stalled = False
        assert _deploy(api, tool_id).status_code == 201
        api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
        assert [d["settled"] for d in _deployments(api, tool_id)] == [None, None]


def test_a_write_the_controller_refuses_is_not_written_when_it_still_shows_its_frame(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The KRC answers the write with status 0 (refused): the write was sent, so tcpcal
    reads once more, finds the frame from before and says nothing was written."""
    with rig("kuka_kvp") as r:
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
        ids = _setup(api, r)
        tool_id = ids["tool"]["id"]
        monkeypatch.setattr(r.sim, "set_var", lambda name, value: False)
        problem = _failed_deploy(api, tool_id, "not_written")
        [dep] = _deployments(api, tool_id)
        np.testing.assert_allclose(dep["read_back"]["position_mm"], PREVIOUS_POSITION, atol=1e-3)
        assert problem["type"].endswith("/controller-refused")
        assert problem["deployment_status"] == "not_written"
        assert NOTHING_WRITTEN in problem["detail"]
        r.assert_holds(PREVIOUS_POSITION, PREVIOUS_Q)


def test_a_deployment_keeps_its_reason(api: Api) -> None:
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        tool_id = ids["tool"]["id"]
        done = _deploy(api, tool_id, {"reason": "  new torch neck, ticket 4411 "})
        assert done.status_code == 201, done.text
        assert done.json()["reason"] == "new torch neck, ticket 4411"
        assert _deployments(api, tool_id)[0]["reason"] == "new torch neck, ticket 4411"
        [event] = _audit(api, tool_id, "tool.deploy")
        assert event["detail"]["reason"] == "new torch neck, ticket 4411"
        assert _deploy(api, tool_id).json()["reason"] is None
        for bad in ("", " ", "x" * 501, 5):
            refused = _deploy(api, tool_id, {"reason": bad})
            assert refused.status_code == 422, (bad, refused.text)
            assert "reason" in refused.text
        assert len(_deployments(api, tool_id)) == 2


def test_an_unverified_deployment_names_the_version_the_controller_held_in_sync(
    api: Api,
) -> None:
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        tool_id = ids["tool"]["id"]
        assert _deploy(api, tool_id).status_code == 201  # v1, in sync
        api.manual(tool_id, [10.0, 0.0, 190.0], activate="always")
        assert api.get(f"/v1/tools/{tool_id}").json()["active_version"] == 2
        r.sim.fault = go_silent("after", WRITE_REQUEST[r.protocol])
        failed = _deploy(api, tool_id)
        assert failed.json()["deployment_status"] == "unverified", failed.text
        assert (
            "written, not confirmed: the controller may hold v2 or v1; the next reconcile "
            "round will tell" in failed.json()["detail"]
        )
