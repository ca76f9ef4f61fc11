"""The watcher: with TCPCAL_RECONCILE_INTERVAL_S > 0, every robot that has a controller is
reconciled that often, by one instance at a time however many serve the fleet.

Each server process runs one watcher thread (started and stopped by the app's lifespan).
Before a round it takes the fleet's watcher lock without waiting: PostgreSQL's
`pg_try_advisory_lock` on a connection held for the round, or on SQLite an flock of
`<database>-watcher.lock` next to the file (as app.db queues SQLite's writers). Whoever
does not get it skips the round. The states a round finds are stored under each tool's row
lock (app.services.controller_states), so a change is recorded once even if two rounds met.
The thread is a daemon that waits on an Event: stop() returns within a second, and a round
stalled on a controller ends at that controller's timeout.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import IO

try:
    import fcntl
except ImportError:  # Windows: no flock; one process per database there
    fcntl = None  # type: ignore[assignment]

from sqlalchemy import text

from app.auth import Principal
from app.db import get_engine, is_sqlite
from app.models import utcnow
from app.services.reconcile import reconcile_robot, robots_with_controller

log = logging.getLogger("tcpcal.watcher")

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


@dataclass
class WatcherStatus:
    """What /ready says of this process's watcher."""

    interval_s: float
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
            "running": self.running,
            "pid": os.getpid(),
            "rounds": self.rounds,
            "rounds_skipped_locked": self.rounds_skipped,
            "last_round_at": None if self.last_round_at is None else self.last_round_at.isoformat(),
            "last_round_s": self.last_round_s,
            "last_error": self.last_error,
        }


class Watcher:
    """Reconciles every robot with a controller every `interval_s`, in a daemon thread."""

    def __init__(self, interval_s: float) -> None:
        self.status = WatcherStatus(interval_s=interval_s)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the loop (its first round at once)."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="tcpcal-watcher", daemon=True)
        self._thread.start()
        self.status.running = True

    def stop(self, timeout_s: float = 0.9) -> None:
        """Ask the loop to end and wait up to `timeout_s` for it (a round stalled on a
        controller ends on its own at that controller's timeout; the thread is a daemon)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        self.status.running = False

    def _loop(self) -> None:
        while not self._stop.is_set():
            started = time.monotonic()
            try:
                self.round()
            except Exception as exc:  # a database outage must not end the loop
                self.status.last_error = f"{type(exc).__name__}: {exc}"
                log.exception("watcher round failed")
            self._stop.wait(max(0.0, self.status.interval_s - (time.monotonic() - started)))

    def round(self) -> None:
        """One round: every robot with a controller, if this instance holds the lock."""
        with fleet_lock() as taken:
            if not taken:
                self.status.rounds_skipped += 1
                return
            started = time.monotonic()
            for robot_id in robots_with_controller():
                if self._stop.is_set():
                    return
                try:
                    reconcile_robot(
                        robot_id=robot_id,
                        actor=WATCHER,
                        trigger="watcher",
                        cancelled=self._stop.is_set,
                    )
                except Exception as exc:  # one robot's failure must not stop the round
                    self.status.last_error = f"robot {robot_id}: {type(exc).__name__}: {exc}"
                    log.exception("watcher could not reconcile robot %s", robot_id)
            self.status.rounds += 1
            self.status.last_round_at = utcnow()
            self.status.last_round_s = round(time.monotonic() - started, 3)


#: This process's watcher, when one runs (for /ready).
CURRENT: Watcher | None = None


def watcher_document() -> dict[str, object]:
    """The watcher's state for /ready: {"enabled": false} when none runs."""
    if CURRENT is None:
        return {"enabled": False}
    return CURRENT.status.document()


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
