"""One publisher per fleet: a lock held in (or beside) the database for the process's life.

- PostgreSQL: a session-level advisory lock (`pg_try_advisory_lock`) on a connection of its
  own, kept open while the publisher runs. The server releases it when that connection ends,
  also when the process is killed with SIGKILL, so a restarted publisher takes over at once.
  https://www.postgresql.org/docs/current/explicit-locking.html#ADVISORY-LOCKS
- SQLite: an exclusive flock(2) on `<database>-publisher.lock` beside the database file (as
  app.storage.db.SqliteWriters does for writers); the kernel releases it when the process dies. An
  in-memory database has no other process to share with, and is refused.

A second publisher waits (polling every `poll` seconds, so SIGTERM still stops it at once)
and starts publishing when the first one stops or dies.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from sqlalchemy import Connection, Engine, text

from app.publish.sink import SinkError
from app.services.audit.outbox import PUBLISHER_LOCK, publisher_lock_file
from app.storage.db import is_sqlite

try:
    import fcntl
except ImportError:  # Windows: no flock
    fcntl = None  # type: ignore[assignment]

log = logging.getLogger(__name__)

# The advisory lock key and the lock file's name are app.services.audit.outbox's, where /metrics
# (app.services.fleet.collector) also reads whether a publisher holds the lock.
__all__ = ["PUBLISHER_LOCK", "FleetLock", "fleet_lock", "lock_path"]


class FleetLock:
    """The publisher's lock; `held()` says whether it is still held (PostgreSQL: the
    connection that holds it still answers)."""

    def __init__(self, connection: Connection | None, file: IO[bytes] | None) -> None:
        self._connection = connection
        self._file = file

    def held(self) -> bool:
        """True while the lock is held (a lost PostgreSQL connection lost the lock too)."""
        if self._connection is None:
            return True
        try:
            self._connection.execute(text("SELECT 1"))
        except Exception:  # any driver error: the session, and the lock with it, is gone
            return False
        return True


def lock_path(engine: Engine) -> Path:
    """The file a SQLite database's publisher locks."""
    database = engine.url.database or ""
    if database in ("", ":memory:") or database.startswith("file:"):
        raise SinkError(
            "the publisher needs a database other processes share: a SQLite file or "
            f"PostgreSQL, not {engine.url.render_as_string(hide_password=True)!r}"
        )
    return publisher_lock_file(database)


@contextlib.contextmanager
def fleet_lock(
    engine: Engine, stopping: threading.Event, *, poll: float = 0.5
) -> Iterator[FleetLock | None]:
    """Hold the fleet's publisher lock for the block; waits while another publisher holds
    it. Yields None when `stopping` was set while waiting."""
    if is_sqlite(engine):
        with _file_lock(lock_path(engine), stopping, poll) as file:
            yield None if file is None else FleetLock(None, file)
        return
    with _advisory_lock(engine, stopping, poll) as connection:
        yield None if connection is None else FleetLock(connection, None)


@contextlib.contextmanager
def _advisory_lock(
    engine: Engine, stopping: threading.Event, poll: float
) -> Iterator[Connection | None]:
    with engine.connect().execution_options(isolation_level="AUTOCOMMIT") as connection:
        waited = False
        while not connection.execute(
            text("SELECT pg_try_advisory_lock(:key)"), {"key": PUBLISHER_LOCK}
        ).scalar_one():
            if not waited:
                log.warning("another publisher holds the fleet lock: waiting for it")
                waited = True
            if stopping.wait(poll):
                yield None
                return
        try:
            yield connection
        finally:
            with contextlib.suppress(Exception):
                connection.execute(text("SELECT pg_advisory_unlock(:key)"), {"key": PUBLISHER_LOCK})


@contextlib.contextmanager
def _file_lock(path: Path, stopping: threading.Event, poll: float) -> Iterator[IO[bytes] | None]:
    if fcntl is None:
        raise SinkError("the publisher on SQLite needs flock (a POSIX system): use PostgreSQL")
    with path.open("ab") as file:
        waited = False
        while True:
            try:
                fcntl.flock(file.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if not waited:
                    log.warning("another publisher holds %s: waiting for it", path)
                    waited = True
                if stopping.wait(poll):
                    yield None
                    return
        file.truncate(0)
        file.write(f"{os.getpid()}\n".encode())
        file.flush()
        try:
            yield file
        finally:
            fcntl.flock(file.fileno(), fcntl.LOCK_UN)
