"""`tcpcal db backup` while 8 threads post calibrations, then `tcpcal db restore`.

Every calibration acknowledged before the backup began must be in it; the SQLite copy must
pass PRAGMA integrity_check; a restore gives exactly the backed-up calibrations back.
"""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text

from testbed.live_server import fresh_database, live_server
from tests.conftest import BACKENDS, PG_URL
from tests.polling import wait_for

pytestmark = pytest.mark.live
TCPCAL = Path(sys.executable).parent / "tcpcal"


def _tcpcal(url: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "TCPCAL_DATABASE_URL": url}
    return subprocess.run(
        [str(TCPCAL), "db", *args], env=env, capture_output=True, text=True, timeout=120
    )


def _calibration_ids(url: str) -> set[str]:
    engine = create_engine(url)
    with engine.connect() as conn:
        ids = {str(r[0]) for r in conn.execute(text("SELECT id FROM calibrations"))}
    engine.dispose()
    return ids


@pytest.mark.parametrize("backend", BACKENDS)
def test_backup_under_writers_holds_every_acknowledged_calibration(
    backend: str, tmp_path: Path
) -> None:
    backup = tmp_path / ("backup.sqlite3" if backend == "sqlite" else "backup.pgdump")
    acknowledged: list[tuple[float, str]] = []
    lock = threading.Lock()
    stop = threading.Event()
    with fresh_database(backend, tmp_path, PG_URL) as url:
        # solvers=0: what is tested is the database under concurrent writers, not the solver
        # pool, whose forkserver cost each of the two workers ~3 CPU-s of a start that hit
        # the 60 s readiness limit at load 5 on 2 cores (testbed/live_server.py)
        with live_server(url, solvers=0) as srv:
            with srv.client() as http:
                robot = http.post("/v1/robots", json={"name": "r"}).json()
                tools = [
                    http.post(f"/v1/robots/{robot['id']}/tools", json={"name": f"t{i}"}).json()
                    for i in range(8)
                ]

            def post(tool_id: str) -> None:
                with srv.client() as http:
                    i = 0
                    while not stop.is_set():
                        body = {"method": "manual", "tcp": {"position_mm": [0, 0, 100 + i]}}
                        r = http.post(f"/v1/tools/{tool_id}/calibrations", json=body)
                        assert r.status_code == 201, r.text
                        with lock:
                            acknowledged.append((time.monotonic(), r.json()["id"]))
                        i += 1

            threads = [threading.Thread(target=post, args=(t["id"],)) for t in tools]
            for thread in threads:
                thread.start()
            under_way = 2 * len(tools)
            wait_for(lambda: len(acknowledged) > under_way, 60, "the writers under way")
            began = time.monotonic()
            done = _tcpcal(url, "backup", str(backup))
            at_backup = len(acknowledged)
            wait_for(lambda: len(acknowledged) > at_backup, 60, "a write after the backup")
            stop.set()
            for thread in threads:
                thread.join(timeout=60)
        assert done.returncode == 0, done.stderr
        before = {cid for at, cid in acknowledged if at < began}
        assert len(before) >= 8
        assert len(acknowledged) > len(before)  # the writers kept going during the backup

        if backend == "sqlite":
            with sqlite3.connect(backup) as conn:
                assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
            backed_up = _calibration_ids(f"sqlite:///{backup}")
        else:
            listing = subprocess.run(
                ["pg_restore", "--list", str(backup)], capture_output=True, text=True, check=True
            )
            assert "TABLE DATA public calibrations" in listing.stdout
            backed_up = None
        if backed_up is not None:
            assert before <= backed_up

        restored = _tcpcal(url, "restore", str(backup))
        assert restored.returncode == 0, restored.stderr
        after_restore = _calibration_ids(url)
        assert before <= after_restore
        assert after_restore < {cid for _, cid in acknowledged}  # later writes are gone
        if backed_up is not None:
            assert after_restore == backed_up
