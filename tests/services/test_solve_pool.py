"""The solver pool: a /v1/solve body and its errors cross the process boundary intact, and
a pool of 0 processes solves in the request's thread with the same answer."""

from __future__ import annotations

import asyncio
import pickle
from collections.abc import Callable, Coroutine
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import pytest

from app.config import get_settings
from app.errors import InvalidInput, NotFound
from app.methods.requests import SOLVE_MODELS
from app.services import solve_pool
from app.services.calibrations.detached import solve_detached
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses

T = TypeVar("T")


def run_async(make: Callable[[], Coroutine[Any, Any, T]]) -> T:
    """asyncio.run in a thread of its own (another test's browser may own this thread's loop)."""
    with ThreadPoolExecutor(1) as thread:
        return thread.submit(lambda: asyncio.run(make())).result()


def test_domain_errors_pickle_with_every_field() -> None:
    error = InvalidInput(
        "convention-mismatch", "fits better as metres", loc=("body", "poses"),
        members={"suggestion": {"format": "kuka_abc"}}, context={"rms": 1.5},
    )  # fmt: skip
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is InvalidInput
    assert (back.kind, back.detail, back.loc) == (error.kind, error.detail, error.loc)
    assert back.members == error.members
    assert back.context == error.context
    assert str(pickle.loads(pickle.dumps(NotFound("no tool x")))) == "no tool x"


@pytest.mark.parametrize("processes", ["2", "0"])
def test_a_solve_in_the_pool_equals_the_solve_in_process(
    processes: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("TCPCAL_SOLVE_PROCESSES", processes)
    get_settings.cache_clear()
    model = next(m for m in SOLVE_MODELS if m.__name__ == "SolveXyzNpoint")
    body = model.model_validate(
        {"method": "xyz_npoint", "format": "kuka_abc",
         "poses": as_poses(simulate_touches(8, seed=4), "kuka_abc")}
    )  # fmt: skip
    pooled = run_async(lambda: solve_pool.run(solve_detached, body, None))
    assert pooled == solve_detached(body, None)
    bad = model.model_validate(
        {"method": "xyz_npoint", "format": "kuka_abc", "poses": [[0] * 6] * 4}
    )
    with pytest.raises(InvalidInput) as raised:
        run_async(lambda: solve_pool.run(solve_detached, bad, None))
    assert raised.value.kind == "out-of-range"  # every flange at the base: not a pose
    assert raised.value.loc[0] == "body"
    get_settings.cache_clear()


@pytest.mark.parametrize(("cores", "solvers"), [(1, 1), (2, 1), (8, 7), (None, 1)])
def test_the_default_leaves_one_core_to_the_event_loop(
    monkeypatch: pytest.MonkeyPatch, cores: int | None, solvers: int
) -> None:
    monkeypatch.delenv("TCPCAL_SOLVE_PROCESSES", raising=False)
    monkeypatch.setattr("os.cpu_count", lambda: cores)
    get_settings.cache_clear()
    try:
        assert solve_pool.processes() == solvers
    finally:
        get_settings.cache_clear()


@pytest.mark.kills
def test_solvers_end_with_a_killed_server_worker() -> None:
    """A worker killed with SIGKILL (uvicorn's health check, the OOM killer) tells its pool
    nothing: the solvers must notice on their own and end, not live on forever."""
    import os
    import signal
    import subprocess
    import sys
    import time

    code = (
        "import os, time\n"
        "os.environ['TCPCAL_SOLVE_PROCESSES'] = '2'\n"
        "from app.services import solve_pool\n"
        "solve_pool.start()\n"
        "print(*solve_pool._get_pool()._processes, flush=True)\n"
        # The watchdogs are waiting on the live worker: each blocks in a join of it, so one
        # that returned early would have ended its solver at once, well within this.
        "time.sleep(0.5)\n"
        "print(solve_pool._get_pool().submit(abs, -7).result(), flush=True)\n"
        "time.sleep(120)\n"
    )
    worker = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert worker.stdout is not None
    solvers = [int(pid) for pid in worker.stdout.readline().split()]
    assert len(solvers) == 2

    def alive(pid: int) -> bool:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True

    assert worker.stdout.readline().strip() == "7"  # a live worker's solvers keep serving
    assert all(alive(pid) for pid in solvers)
    worker.send_signal(signal.SIGKILL)
    worker.wait()
    deadline = time.monotonic() + 10
    while any(alive(pid) for pid in solvers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(alive(pid) for pid in solvers)
