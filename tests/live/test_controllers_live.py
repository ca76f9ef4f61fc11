"""Controllers against real uvicorn servers: a stalled controller never stalls the server
(GET tcp is served while a deployment waits on it), and two instances on PostgreSQL with the
watcher on record each drift once."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
from sqlalchemy import create_engine, text

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.api.controller_rigs import rig
from tests.api.test_deployments import ACTIVE_POSITION, ACTIVE_Q
from tests.conftest import PG_URL
from tests.polling import wait_for

pytestmark = pytest.mark.live
#: Each poll of the audit counts opens an engine on PostgreSQL: a tenth of a second apart.
POLL_S = 0.1


def _set_up(http: httpx.Client, controller: dict[str, Any]) -> tuple[str, str]:
    robot = http.post("/v1/robots", json={"name": "kr16"}).json()
    http.put(f"/v1/robots/{robot['id']}/controller", json=controller).raise_for_status()
    tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "torch", "slot": 3}).json()
    body = {"method": "manual", "tcp": {"position_mm": ACTIVE_POSITION, "quaternion": ACTIVE_Q}}
    http.post(f"/v1/tools/{tool['id']}/calibrations", json=body).raise_for_status()
    return robot["id"], tool["id"]


def test_get_tcp_is_served_while_a_stalled_controller_holds_a_deployment(tmp_path: Path) -> None:
    timeout_s = 3.0
    with (
        rig("kuka_kvp") as r,
        fresh_database("sqlite", tmp_path, None) as url,
        live_server(url, workers=1, solvers=0) as srv,
        srv.client() as http,
    ):
        _, tool_id = _set_up(http, r.controller_body(timeout_s=timeout_s))
        r.sim.stalled = True
        result: dict[str, Any] = {}

        def deploy() -> None:
            started = time.monotonic()
            with srv.client() as client:
                result["response"] = client.post(f"/v1/tools/{tool_id}/deployments", json={})
            result["elapsed"] = time.monotonic() - started

        worker = threading.Thread(target=deploy)
        worker.start()
        time.sleep(0.3)  # the deployment is now waiting on the stalled controller
        latencies: list[float] = []
        while worker.is_alive() and len(latencies) < 40:
            started = time.monotonic()
            got = http.get(f"/v1/tools/{tool_id}/tcp")
            latencies.append(time.monotonic() - started)
            assert got.status_code == 200
            time.sleep(0.02)
        # no transaction is held open meanwhile: a write (SQLite: one writer at a time) passes
        started = time.monotonic()
        assert http.post("/v1/robots", json={"name": "written-meanwhile"}).status_code == 201
        write_s = time.monotonic() - started
        served_while_waiting = worker.is_alive()
        worker.join(timeout_s + 5)
        assert served_while_waiting
        assert len(latencies) >= 10
        assert max(latencies) < 0.5, latencies
        assert write_s < 0.5
        response = result["response"]
        assert response.status_code == 502
        assert response.json()["type"].endswith("/controller-unreachable")
        assert result["elapsed"] < timeout_s + 1


def _events(url: str, action: str) -> int:
    engine = create_engine(url)
    try:
        with engine.connect() as conn:
            return int(
                conn.execute(
                    text("SELECT count(*) FROM audit_events WHERE action = :a"), {"a": action}
                ).scalar_one()
            )
    finally:
        engine.dispose()


@pytest.mark.skipif(not PG_URL, reason="TCPCAL_TEST_DATABASE_URL (PostgreSQL) is not set")
def test_two_instances_with_the_watcher_record_each_drift_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Two instances of one worker each: two watchers in two processes share the robot by its
    # lease (issue 50; each round one of them reads it), as four did with two workers each
    # (at 5 s of CPU more). Rounds every half second;
    # how soon a round finds a change is tests/services/controllers/test_watcher.py's subject, so a
    # change is waited for generously here (a loaded machine delays rounds).
    interval = 0.5
    settle = 10.0
    monkeypatch.setenv("TCPCAL_RECONCILE_INTERVAL_S", str(interval))
    with (
        rig("kuka_kvp") as r,
        fresh_database("postgresql", tmp_path, PG_URL) as url,
        live_server(url, workers=1, solvers=0) as one,
        live_server(url, workers=1, solvers=0) as two,
    ):
        servers: list[LiveServer] = [one, two]
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)
        with one.client() as http:
            robot_id, tool_id = _set_up(http, r.controller_body())
        wait_for(lambda: _events(url, "controller.in_sync") >= 1, settle, "in sync", every=POLL_S)
        for srv in servers:
            watcher = httpx.get(f"{srv.url}/ready").json()["watcher"]
            assert watcher["enabled"] is True
            assert watcher["interval_s"] == interval
        moved = [ACTIVE_POSITION[0], ACTIVE_POSITION[1], ACTIVE_POSITION[2] - 0.3]
        r.set_behind_back(moved, ACTIVE_Q)
        wait_for(
            lambda: _events(url, "controller.drifted") >= 1, settle, "drift recorded", every=POLL_S
        )
        time.sleep(4 * interval)  # every watcher of both instances has had rounds since
        assert _events(url, "controller.drifted") == 1
        assert _events(url, "controller.in_sync") == 1
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)
        wait_for(
            lambda: _events(url, "controller.in_sync") >= 2, settle, "back in sync", every=POLL_S
        )
        r.set_behind_back(moved, ACTIVE_Q)
        wait_for(
            lambda: _events(url, "controller.drifted") >= 2, settle, "second drift", every=POLL_S
        )
        time.sleep(3 * interval)
        assert _events(url, "controller.drifted") == 2
        assert _events(url, "controller.in_sync") == 2
        with two.client() as http:
            row = http.get("/v1/tools", params={"robot_id": robot_id}).json()["items"][0]
            assert row["controller"]["state"] == "drifted"
            assert row["id"] == tool_id
