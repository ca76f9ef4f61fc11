"""The watcher in the app's lifespan: drift found within two intervals, one audit event per
change, its state in /ready, and a stop within a second even when a controller stalls."""

from __future__ import annotations

import time

import pytest
from sqlalchemy import text

from app.db import get_engine
from tests.api.controller_rigs import TIMEOUT_S, rig
from tests.api.test_deployments import ACTIVE_POSITION, ACTIVE_Q, _setup
from tests.conftest import Api, Database

INTERVAL_S = 0.5


@pytest.fixture
def watching(monkeypatch: pytest.MonkeyPatch) -> float:
    """The watcher on (set before the app starts)."""
    monkeypatch.setenv("TCPCAL_RECONCILE_INTERVAL_S", str(INTERVAL_S))
    return INTERVAL_S


def _count(tool_id: str, action: str) -> int:
    with get_engine().connect() as conn:
        return int(
            conn.execute(
                text("SELECT count(*) FROM audit_events WHERE tool_id = :t AND action = :a"),
                {"t": tool_id, "a": action},
            ).scalar_one()
        )


def _row(api: Api, robot_id: str) -> dict[str, object]:
    return dict(api.get("/v1/tools", params={"robot_id": robot_id}).json()["items"][0])


def test_the_watcher_finds_drift_within_two_intervals_and_records_it_once(
    watching: float, api: Api
) -> None:
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        tool_id, robot_id = ids["tool"]["id"], ids["robot"]["id"]
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)  # the controller holds the active TCP
        _wait_for(api, robot_id, "in_sync", 2 * watching)
        ready = api.client.get("/ready").json()["watcher"]
        assert ready["enabled"] is True
        assert ready["interval_s"] == watching
        assert ready["rounds"] >= 1
        assert ready["running"] is True
        r.set_behind_back(
            [ACTIVE_POSITION[0], ACTIVE_POSITION[1] + 0.2, ACTIVE_POSITION[2]], ACTIVE_Q
        )
        started = time.monotonic()
        row = _wait_for(api, robot_id, "drifted", 2 * watching)
        assert time.monotonic() - started <= 2 * watching
        assert row["attention"] == ["controller_drifted"]
        time.sleep(3 * watching)  # three more rounds find it drifted still
        assert _count(tool_id, "controller.drifted") == 1
        assert _count(tool_id, "controller.in_sync") == 1
        r.sim.stop()
        _wait_for(api, robot_id, "unreachable", 2 * watching + TIMEOUT_S + 1.0)  # + its timeout
        assert _count(tool_id, "controller.unreachable") == 1


def _wait_for(api: Api, robot_id: str, state: str, within_s: float) -> dict[str, object]:
    deadline = time.monotonic() + within_s
    while True:
        row = _row(api, robot_id)
        controller = row["controller"]
        if isinstance(controller, dict) and controller["state"] == state:
            return row
        if time.monotonic() > deadline:
            raise AssertionError(f"not {state} within {within_s} s: {row}")
        time.sleep(0.05)


def test_the_watcher_stops_within_a_second_while_a_controller_stalls(api: Api) -> None:
    from app.watcher import Watcher

    with rig("kuka_kvp") as r:
        _setup(api, r)
        r.sim.stalled = True
        watcher = Watcher(0.2)
        watcher.start()
        time.sleep(0.5)  # a round is now waiting for the stalled controller (2 s timeout)
        started = time.monotonic()
        watcher.stop()
        assert time.monotonic() - started < 1.0
        assert watcher.status.running is False
        assert watcher._thread is not None
        watcher._thread.join(3)  # its round ends at the controller's timeout, storing nothing
        assert not watcher._thread.is_alive()


def test_one_round_at_a_time_per_database(api: Api) -> None:
    from app.watcher import fleet_lock

    with fleet_lock() as first:
        assert first is True
        with fleet_lock() as second:
            assert second is False
    with fleet_lock() as again:
        assert again is True


def test_another_process_holding_the_sqlite_lock_keeps_this_one_out(api: Api, db: Database) -> None:
    """The flock next to the database file: held by another process, this one skips."""
    import subprocess
    import sys

    from app.db import get_engine as engine_of
    from app.watcher import fleet_lock

    if db.backend != "sqlite":
        pytest.skip("the advisory lock of PostgreSQL is tested with two live servers")
    path = f"{engine_of().url.database}-watcher.lock"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import fcntl, sys, time\n"
            f"f = open({path!r}, 'ab'); fcntl.flock(f.fileno(), fcntl.LOCK_EX)\n"
            "print('held', flush=True); time.sleep(30)",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None
        assert holder.stdout.readline().strip() == "held"
        with fleet_lock() as taken:
            assert taken is False
    finally:
        holder.kill()
        holder.wait()
    with fleet_lock() as taken:
        assert taken is True
