"""Under load the event loop never waits for a database connection held by a request that is
itself waiting for the loop: many slow fleet reads (each holding a pooled connection between
its dependencies and its endpoint) at once with active-TCP reads and solves served on the
loop all complete. Before the loop had its own connection this stalled the whole server."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from testbed.live_server import fresh_database, http_client, live_server
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses

pytestmark = pytest.mark.live


def test_loop_side_reads_never_deadlock_with_thread_side_sessions(tmp_path: Path) -> None:
    with fresh_database("sqlite", tmp_path, None) as url, live_server(url, workers=1) as srv:
        with srv.client() as http:
            robot = http.post("/v1/robots", json={"name": "r"}).json()
            tools = [
                http.post(f"/v1/robots/{robot['id']}/tools", json={"name": f"t{i}"}).json()
                for i in range(30)
            ]
            tid = tools[0]["id"]
            http.post(
                f"/v1/tools/{tid}/calibrations",
                json={"method": "manual", "tcp": {"position_mm": [0, 0, 150]}},
            ).raise_for_status()
        solve = {"method": "xyz_npoint", "format": "xyz_wxyz",
                 "poses": as_poses(simulate_touches(8, seed=1))}  # fmt: skip
        auth = {"Authorization": f"Bearer {srv.admin_key}"}

        def call(i: int) -> int:
            with http_client(srv.url, headers=auth, timeout=30) as client:
                if i % 4 == 0:
                    return client.post("/v1/solve", json=solve).status_code
                if i % 4 == 1:
                    return client.get(f"/v1/tools/{tid}/tcp").status_code
                return client.get("/v1/tools", params={"limit": 50}).status_code

        with ThreadPoolExecutor(48) as pool:
            codes = list(pool.map(call, range(240)))
        assert codes.count(200) == 240, sorted(set(codes))
