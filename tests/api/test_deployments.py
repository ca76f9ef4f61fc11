"""Deploy a tool's active TCP to each controller's simulator, read back, reconcile."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sqlalchemy import text

from app.db import get_engine
from tests.api.controller_rigs import PROTOCOLS, TIMEOUT_S, Rig, rig
from tests.conftest import Api
from tests.controllers.helpers import angle_between_deg

ACTIVE_POSITION = [12.5, -3.25, 187.125]
ACTIVE_Q = [
    float(v) for v in np.roll(Rotation.from_euler("ZYX", [30, -20, 10], degrees=True).as_quat(), 1)
]
PREVIOUS_POSITION = [1.0, 2.0, 150.0]
PREVIOUS_Q = [
    float(v) for v in np.roll(Rotation.from_euler("ZYX", [5, 0, 0], degrees=True).as_quat(), 1)
]


@pytest.fixture(autouse=True)
def secret_key(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """ABB controllers take a password, stored encrypted under this key."""
    from app.config import get_settings

    monkeypatch.setenv("TCPCAL_SECRET_KEY", "deployment-tests-secret-key-0123456789")
    get_settings.cache_clear()
    yield
    get_settings.cache_clear()


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


def _deploy(api: Api, tool_id: str, **headers: str) -> Any:
    return api.post(f"/v1/tools/{tool_id}/deployments", {}, scope="calibrate", headers=headers)


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
    assert row["attention"] == ["controller_drifted"]
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
