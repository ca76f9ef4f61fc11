"""The watcher: with TCPCAL_RECONCILE_INTERVAL_S > 0, every robot that has a controller is
reconciled that often, by one instance at a time however many serve the fleet.

Each server process runs one watcher thread (started and stopped by the app's lifespan).
Before a round it takes the fleet's watcher lock without waiting: PostgreSQL's
`pg_try_advisory_lock` on a connection held for the round, or on SQLite an flock of
`<database>-watcher.lock` next to the file (as app.storage.db queues SQLite's writers). Whoever
does not get it skips the round. The states a round finds are stored under each tool's row
lock (app.services.controllers.states), so a change is recorded once even if two rounds met.

A round reads its robots' controllers concurrently, at most TCPCAL_RECONCILE_CONCURRENCY at
once (a ReadPool of daemon threads), and each robot's states are stored as soon as its own
read ends: read one by one, a controller that hung for its timeout_s (30 s in the trial)
delayed every other robot's state change by as much. A robot whose read is still in flight
is not read again by the next round (no pile-up of threads or connections on a hung
controller), and while any read is in flight the fleet lock stays held into the next round,
so no other instance starts those controllers meanwhile.
The threads are daemons: stop() returns within a second, and a read stalled on a controller
ends at that controller's timeout, storing nothing.
"""

from __future__ import annotations

import logging
import os
import queue
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import IO

try:
    import fcntl
except ImportError:  # Windows: no flock; one process per database there
    fcntl = None  # type: ignore[assignment]

from sqlalchemy import text

from app.config import get_settings
from app.errors import ConnectorMissing
from app.logs import get_logger
from app.security.auth import Principal
from app.services.controllers.reconcile import reconcile_robot, robots_with_controller
from app.storage.db import get_engine, is_sqlite
from app.storage.models import utcnow

log = logging.getLogger("tcpcal.watcher")
#: The same logger's structured lines (an event and its fields).
events = get_logger("tcpcal.watcher")

#: Who the watcher's audit events name.
WATCHER = Principal(key_id="watcher", name="watcher", scope="read")
#: The advisory lock's key on PostgreSQL ("tcpcal.watcher" as a 64-bit number).
ADVISORY_KEY = int.from_bytes(b"tcpcal.w", "big") & 0x7FFF_FFFF_FFFF_FFFF

_THREADS_LOCK = threading.Lock()


@contextmanager
def fleet_lock() -> Iterator[bool]:
    """Try to take the fleet's watcher lock without waiting; yields whether it was taken."""
    engine = get_engine()
    if not is_sqlite(engine):
        with engine.connect() as conn:
            taken = bool(
                conn.execute(text("SELECT pg_try_advisory_lock(:k)"), {"k": ADVISORY_KEY}).scalar()
            )
            conn.commit()
            try:
                yield taken
            finally:
                if taken:
                    conn.execute(text("SELECT pg_advisory_unlock(:k)"), {"k": ADVISORY_KEY})
                    conn.commit()
        return
    database = engine.url.database or ""
    if not _THREADS_LOCK.acquire(blocking=False):
        yield False
        return
    try:
        if fcntl is None or database in ("", ":memory:") or database.startswith("file:"):
            yield True
            return
        with _flock(Path(f"{database}-watcher.lock")) as taken:
            yield taken
    finally:
        _THREADS_LOCK.release()


@contextmanager
def _flock(path: Path) -> Iterator[bool]:
    handle: IO[bytes] = path.open("ab")
    try:
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)
    finally:
        handle.close()


class ReadPool:
    """At most `size` daemon threads, each reconciling one robot at a time. A robot is in
    flight from when it is offered until its read has ended and its states are stored;
    offering it again meanwhile does nothing, so a hung controller is read once, not once
    per round."""

    def __init__(self, size: int, work: Callable[[str], None]) -> None:
        self.size = size
        self._work = work
        self._queue: queue.SimpleQueue[str | None] = queue.SimpleQueue()  # None: end
        self._in_flight: set[str] = set()
        self._changed = threading.Condition()
        self._threads: list[threading.Thread] = []
        self._stopped = False

    def offer(self, robot_ids: Iterable[str]) -> set[str]:
        """Queue each of these robots that is not in flight; the ones queued now."""
        with self._changed:
            if self._stopped:
                return set()
            fresh = [robot_id for robot_id in robot_ids if robot_id not in self._in_flight]
            self._in_flight.update(fresh)
            for robot_id in fresh:
                self._queue.put(robot_id)
            # threads are started as the work needs them, never more than `size`
            while len(self._threads) < min(self.size, len(self._in_flight)):
                thread = threading.Thread(
                    target=self._run, name=f"tcpcal-reconcile-{len(self._threads) + 1}", daemon=True
                )
                thread.start()
                self._threads.append(thread)
        return set(fresh)

    def in_flight(self) -> int:
        """How many robots are queued or being read."""
        with self._changed:
            return len(self._in_flight)

    def wait(self, robot_ids: set[str], timeout_s: float) -> bool:
        """Wait up to `timeout_s` until none of these robots is in flight (or the pool
        stopped); whether that happened."""
        with self._changed:
            return self._changed.wait_for(
                lambda: self._stopped or not robot_ids & self._in_flight, timeout_s
            )

    def stop(self) -> None:
        """Take no more work; idle threads end now, busy ones when their read ends."""
        with self._changed:
            self._stopped = True
            self._changed.notify_all()
            for _ in self._threads:
                self._queue.put(None)

    def join(self, until: float) -> None:
        """Wait for the threads to end, until the monotonic time `until` at the latest."""
        for thread in list(self._threads):
            thread.join(max(0.0, until - time.monotonic()))

    def _run(self) -> None:
        while True:
            robot_id = self._queue.get()
            if robot_id is None or self._stopped:
                return
            try:
                self._work(robot_id)
            finally:
                with self._changed:
                    self._in_flight.discard(robot_id)
                    self._changed.notify_all()


@dataclass
class WatcherStatus:
    """What /ready says of this process's watcher."""

    interval_s: float
    concurrency: int
    running: bool = False
    rounds: int = 0
    rounds_skipped: int = 0
    last_round_at: datetime | None = None
    last_round_s: float | None = None
    last_error: str | None = None
    errors: dict[str, str] = field(default_factory=dict)

    def document(self) -> dict[str, object]:
        return {
            "enabled": True,
            "interval_s": self.interval_s,
            "concurrency": self.concurrency,
            "running": self.running,
            "pid": os.getpid(),
            "rounds": self.rounds,
            "rounds_skipped_locked": self.rounds_skipped,
            "last_round_at": None if self.last_round_at is None else self.last_round_at.isoformat(),
            "last_round_s": self.last_round_s,
            "last_error": self.last_error,
        }


class Watcher:
    """Reconciles every robot with a controller every `interval_s`, in a daemon thread, at
    most `concurrency` controllers at once (default TCPCAL_RECONCILE_CONCURRENCY)."""

    def __init__(self, interval_s: float, concurrency: int | None = None) -> None:
        size = get_settings().reconcile_concurrency if concurrency is None else concurrency
        self.status = WatcherStatus(interval_s=interval_s, concurrency=size)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._pool = ReadPool(size, self._reconcile)
        #: The fleet lock while this watcher holds it (across rounds while reads are in flight)
        self._lock: ExitStack | None = None
        #: Robots whose protocol this tcpcal has no connector for, warned of once each
        self._no_connector: set[str] = set()

    def document(self) -> dict[str, object]:
        """The watcher's state for /ready, with the reads now in flight."""
        return self.status.document() | {"reads_in_flight": self._pool.in_flight()}

    def start(self) -> None:
        """Start the loop (its first round at once)."""
        self._stop.clear()
        self._pool = ReadPool(self.status.concurrency, self._reconcile)
        self._thread = threading.Thread(target=self._loop, name="tcpcal-watcher", daemon=True)
        self._thread.start()
        self.status.running = True

    def stop(self, timeout_s: float = 0.9) -> None:
        """Ask the loop and its reads to end and wait up to `timeout_s` for them: a read that
        has ended stores nothing after this, and one storing what it found finishes first (the
        database may be closed next). A read stalled on a controller ends on its own at that
        controller's timeout, storing nothing; the threads are daemons."""
        until = time.monotonic() + timeout_s
        self._stop.set()
        self._pool.stop()
        if self._thread is not None:
            self._thread.join(timeout_s)
        self._pool.join(until)
        self.status.running = False

    def _loop(self) -> None:
        try:
            while not self._stop.is_set():
                started = time.monotonic()
                try:
                    self.round()
                except Exception as exc:  # a database outage must not end the loop
                    self.status.last_error = f"{type(exc).__name__}: {exc}"
                    log.exception("watcher round failed")
                self._stop.wait(max(0.0, self.status.interval_s - (time.monotonic() - started)))
        finally:
            self._release()

    def round(self) -> None:
        """One round, if this instance holds the lock: every robot with a controller whose
        last read has ended is read again; the round waits up to the interval for them."""
        if not self._take_lock():
            self.status.rounds_skipped += 1
            return
        try:
            started = time.monotonic()
            offered = self._pool.offer(robots_with_controller())
            self._pool.wait(offered, self.status.interval_s)
            if self._stop.is_set():
                return
            self.status.rounds += 1
            self.status.last_round_at = utcnow()
            self.status.last_round_s = round(time.monotonic() - started, 3)
        finally:
            if self._pool.in_flight() == 0:  # else held into the next round
                self._release()

    def _take_lock(self) -> bool:
        if self._lock is not None:
            return True
        stack = ExitStack()
        if not stack.enter_context(fleet_lock()):
            stack.close()
            return False
        self._lock = stack
        return True

    def _release(self) -> None:
        stack, self._lock = self._lock, None
        if stack is not None:
            stack.close()

    def _reconcile(self, robot_id: str) -> None:
        """One robot, in a pool thread: its states are stored as its read ends."""
        if self._stop.is_set():
            return
        try:
            reconcile_robot(
                robot_id=robot_id, actor=WATCHER, trigger="watcher", cancelled=self._stop.is_set
            )
        except ConnectorMissing as exc:  # stored for a later tcpcal: not a fault of this one
            self.status.last_error = f"robot {robot_id}: {exc}"
            if robot_id not in self._no_connector:
                self._no_connector.add(robot_id)
                events.warning("watcher.no_connector", robot_id=robot_id, detail=str(exc))
            return
        except Exception as exc:  # one robot's failure must not stop the others
            self.status.last_error = f"robot {robot_id}: {type(exc).__name__}: {exc}"
            log.exception("watcher could not reconcile robot %s", robot_id)


#: This process's watcher, when one runs (for /ready).
CURRENT: Watcher | None = None


def watcher_document() -> dict[str, object]:
    """The watcher's state for /ready: {"enabled": false} when none runs."""
    if CURRENT is None:
        return {"enabled": False}
    return CURRENT.document()


def start_watcher(interval_s: float) -> Watcher:
    """Start this process's watcher."""
    global CURRENT
    watcher = Watcher(interval_s)
    watcher.start()
    CURRENT = watcher
    return watcher


def stop_watcher() -> None:
    """Stop this process's watcher, within a second."""
    global CURRENT
    if CURRENT is not None:
        CURRENT.stop()
        CURRENT = None
