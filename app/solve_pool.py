"""CPU-bound solving off the event loop and out of the GIL: a process pool sized to the cores.

A solve holds the CPU for milliseconds to a second (the robust N-point fit, the convention
diagnosis re-solving other readings). Run in the request's thread it competes for the GIL with
every other request of the worker, so one burst of solves stretched every read's latency.
Here each server worker process owns a pool of `solve_processes` processes (default: one per
core), started lazily with the forkserver method (no fork of a threaded server), and awaits
it: the event loop stays free to serve reads, and a burst of solves queues in the pool
instead of in the loop. The pool lives as long as its worker process (the executor joins
its processes at exit). Errors raised in a solver process come back as they were raised
(DomainError pickles with every field).
"""

from __future__ import annotations

import asyncio
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from typing import ParamSpec, TypeVar

from starlette.concurrency import run_in_threadpool

from app.config import get_settings

P = ParamSpec("P")
T = TypeVar("T")

_pool: ProcessPoolExecutor | None = None


def processes() -> int:
    """How many solver processes a server worker uses (0: solve in the request's thread)."""
    configured = get_settings().solve_processes
    return os.cpu_count() or 1 if configured is None else configured


def _get_pool() -> ProcessPoolExecutor:
    global _pool
    if _pool is None:
        context = multiprocessing.get_context("forkserver")
        _pool = ProcessPoolExecutor(max_workers=processes(), mp_context=context)
    return _pool


async def run(fn: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> T:
    """fn(*args, **kwargs) in a solver process (its arguments and result must pickle)."""
    if processes() == 0:
        return await run_in_threadpool(fn, *args, **kwargs)
    loop = asyncio.get_running_loop()
    return await loop.run_in_executor(_get_pool(), partial(fn, *args, **kwargs))
