"""CPU-bound solving off the event loop and out of the GIL: a process pool sized to the cores.

A solve holds the CPU for milliseconds to a second (the robust N-point fit, the convention
diagnosis re-solving other readings). Run in the request's thread it competes for the GIL with
every other request of the worker, so one burst of solves stretched every read's latency.
Here each server worker process owns a pool of `solve_processes` processes (default: one per
core but one, which is left to the event loop), started lazily with the forkserver method
(no fork of a threaded server), and awaits it: the event loop stays free to serve reads,
and a burst of solves queues in the pool instead of in the loop. The pool lives as long as
its worker process (the executor joins its processes at exit). Errors raised in a solver
process come back as they were raised (DomainError pickles with every field).

A calibration is solved and stored by one call here
(app.services.calibrations.writes.solve_and_submit): the solver process writes it to the
database itself, on its own engine, queued with every other writer
(app.storage.db.SqliteWriters on SQLite, the tool's row lock on PostgreSQL).
"""

from __future__ import annotations

import asyncio
import importlib
import multiprocessing
import os
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from functools import partial
from typing import ParamSpec, TypeVar

from anyio.to_thread import run_sync

from app.config import get_settings

P = ParamSpec("P")
T = TypeVar("T")

_pool: ProcessPoolExecutor | None = None
#: The modules each solver process imports as it starts (given to `start`): the solve path.
_preload: tuple[str, ...] = ()


def processes() -> int:
    """How many solver processes a server worker uses (0: solve in the request's thread)."""
    configured = get_settings().solve_processes
    return default_processes() if configured is None else configured


def default_processes() -> int:
    """One per core but one."""
    # One core is the event loop's: with as many solvers as cores, a burst of solves took the
    # CPU from the loop that answers them (wrk, 2 cores, 1 worker: 298 solves/s and p99 80 ms
    # with 2 solver processes, 358/s and 69 ms with 1; GET tcp 304 0.77x -> 0.85x bare).
    return max(1, (os.cpu_count() or 1) - 1)


def _get_pool() -> ProcessPoolExecutor:
    global _pool
    if _pool is None:
        context = multiprocessing.get_context("forkserver")
        # The forkserver imports the solve path once and each solver forks from it with it
        # imported: each solver used to import it again (numpy, scipy, the methods: about
        # 1.5 s of CPU each, 5.4 s to start 3 solvers against 1.8 s now), and a pool that
        # replaces a dead solver (run()) now starts at once. "__main__" is the default
        # preload: without it each solver would run the main script (`tcpcal`) again. What the
        # solve path is, the app names (start(preload=...)): this module sits below it.
        context.set_forkserver_preload(["__main__", *_preload])
        _pool = ProcessPoolExecutor(
            max_workers=processes(),
            mp_context=context,
            initializer=_start_solver,
            initargs=(_preload,),
        )
    return _pool


def _start_solver(preload: tuple[str, ...]) -> None:
    """Each solver process has the solve path imported as it starts (`preload`: numpy, scipy,
    the methods: about a second, once in the forkserver), not in the middle of its first
    request, logs as its server worker does (the audit events of the calibrations it stores),
    leaves what it imported out of later garbage collections (see app.main.settle_heap), and
    ends with its server worker."""
    import gc
    import signal

    for module in preload:  # the forkserver imported them: here at no cost
        importlib.import_module(module)

    # Ctrl-C in a terminal reaches the whole process group: the server worker stops its pool
    # (stop()), so a solver need not, and must not die mid-call with a KeyboardInterrupt.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from app.logs import SERVING_ENV, configure_logging

    if os.environ.get(SERVING_ENV):
        configure_logging()

    gc.collect()
    gc.freeze()
    threading.Thread(target=_exit_with_parent, name="solver-watchdog", daemon=True).start()


def _exit_with_parent() -> None:
    """A pool's processes wait on its queue for the next call and stop only when told to by
    the process that made the pool. A worker that is killed (by uvicorn's health check, the
    OOM killer, kill -9) tells nobody: its solvers, and the forkserver they keep alive, then
    lived on, about 100 MB each; the test suite left 70 behind per run. Here each solver
    waits for the process that made the pool to end and then ends too."""
    parent = multiprocessing.parent_process()
    if parent is None:  # not started by a pool (cannot happen with the forkserver context)
        return
    parent.join()
    os._exit(0)


def start(*, preload: tuple[str, ...] = ()) -> None:
    """Start the solver processes now (at server start-up) so that no request waits for them,
    each importing the modules named in `preload` as it starts."""
    global _preload
    _preload = preload
    if processes() > 0:
        pool = _get_pool()
        for future in [pool.submit(int) for _ in range(processes())]:
            future.result()


async def run(fn: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> T:
    """fn(*args, **kwargs) in a solver process (its arguments and result must pickle)."""
    if processes() == 0:
        return await run_sync(partial(fn, *args, **kwargs))
    loop = asyncio.get_running_loop()
    call = partial(fn, *args, **kwargs)
    try:
        return await loop.run_in_executor(_get_pool(), call)
    except BrokenProcessPool:
        # A solver process died (killed, out of memory): a broken pool refuses all work, so
        # replace it and give this solve one more try before answering 500.
        _discard_pool()
        return await loop.run_in_executor(_get_pool(), call)


def stop() -> None:
    """Stop the solver processes and wait for them (at server shutdown): a pool left to the
    interpreter's exit leaves its queues' semaphores behind, and the resource tracker
    reported them as leaked (10 with `tcpcal serve --workers 2` stopped by Ctrl-C)."""
    global _pool
    if _pool is not None:
        _pool.shutdown(wait=True, cancel_futures=True)
        _pool = None


def _discard_pool() -> None:
    global _pool
    if _pool is not None:
        _pool.shutdown(wait=False, cancel_futures=True)
        _pool = None
