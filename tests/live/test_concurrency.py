"""Against a real 2-worker uvicorn: version numbers stay 1..n under concurrent submissions,
and concurrent activations leave exactly one active version, the last one recorded."""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TypeVar

import pytest

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.conftest import BACKENDS, PG_URL

pytestmark = pytest.mark.live
N = 20
T = TypeVar("T")


@pytest.fixture(params=BACKENDS)
def server(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[LiveServer]:
    # solvers=0: what is tested is the database under concurrent writers, not the solver
    # pool, whose forkserver cost each of the two workers ~3 CPU-s of a start that hit
    # the 60 s readiness limit at load 5 on 2 cores (testbed/live_server.py)
    with fresh_database(request.param, tmp_path, PG_URL) as url, live_server(url, solvers=0) as srv:
        yield srv


def _all_at_once(fn: Callable[[int], T], n: int) -> list[T]:
    barrier = threading.Barrier(n)

    def run(i: int) -> T:
        barrier.wait()
        return fn(i)

    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(run, range(n)))


def test_concurrent_calibrations_and_activations(server: LiveServer) -> None:
    with server.client() as http:
        robot = http.post("/v1/robots", json={"name": "live"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "t", "slot": 1}).json()
    tool_path = f"/v1/tools/{tool['id']}"

    def submit(i: int) -> tuple[int, int]:
        with server.client() as http:
            r = http.post(
                f"{tool_path}/calibrations",
                json={"method": "manual", "tcp": {"position_mm": [0, 0, 100 + i]}, "note": str(i)},
            )
            return r.status_code, int(r.json().get("version", 0))

    results = _all_at_once(submit, N)
    assert [status for status, _ in results] == [201] * N
    assert sorted(v for _, v in results) == list(range(1, N + 1))

    with server.client() as http:
        versions = http.get(f"{tool_path}/versions").json()["items"]
    assert [v["version"] for v in versions] == list(range(1, N + 1))
    # each version holds the TCP its own submission sent
    assert {v["note"]: v["tcp"]["position_mm"][2] for v in versions} == {
        str(i): 100 + i for i in range(N)
    }

    def activate(i: int) -> int:
        with server.client() as http:
            return http.post(f"{tool_path}/versions/{i + 1}/activate").status_code

    assert _all_at_once(activate, N) == [200] * N
    with server.client() as http:
        listing = http.get(f"{tool_path}/versions").json()
        tool_now = http.get(tool_path).json()
    active = [v["version"] for v in listing["items"] if v["active"]]
    explicit = [a for a in listing["activations"] if a["reason"] == "explicit"]
    assert len(active) == 1
    assert len(explicit) == N
    assert sorted(a["version"] for a in explicit) == list(range(1, N + 1))
    assert active[0] == listing["activations"][-1]["version"] == tool_now["active_version"]
    # the history chains: each activation's previous_version is the one before it
    chain = listing["activations"]
    assert all(b["previous_version"] == a["version"] for a, b in itertools.pairwise(chain))
