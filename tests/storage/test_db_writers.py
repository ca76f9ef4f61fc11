"""SQLite writers queue across threads and processes (app.storage.db.SqliteWriters), and each
process keeps one engine per database URL (a solver process stores calibrations through the one it
is handed)."""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from sqlalchemy import text

from app.storage.db import (
    SqliteWriters,
    dispose_engines,
    engine_for,
    get_engine,
    session_scope,
    sqlite_writers,
)

REPO = Path(__file__).resolve().parents[2]

# A writer in another process: takes the queue and says when, holds it until told (a line on
# its standard input, or at once with "0"), says when it let go.
_OTHER_WRITER = """
import sys, time
from pathlib import Path
from app.storage.db import SqliteWriters
writers = SqliteWriters(Path(sys.argv[1]))
print("waiting", flush=True)
with writers:
    print(time.time(), flush=True)
    if sys.argv[2] != "0":
        sys.stdin.readline()
    released = time.time()
print(released, flush=True)
"""


def _other_writer(lock: Path, *, hold: bool) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", _OTHER_WRITER, str(lock), "1" if hold else "0"],
        cwd=REPO,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "waiting"
    return proc


def _wait_until_blocked(pid: int, timeout_s: float = 30.0) -> None:
    """Until process `pid` waits for an flock: the kernel lists each waiter in /proc/locks
    as a line marked "->" with the waiting process's id (proc(5)). An event, not a sleep: a
    sleep of 0.5 s here once only hoped the other process had reached the queue."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for line in Path("/proc/locks").read_text().splitlines():
            fields = line.split()
            if "->" in fields and "FLOCK" in fields and str(pid) in fields:
                return
        time.sleep(0.001)
    raise AssertionError(f"process {pid} never waited for the writers' lock")


def test_a_writer_of_another_process_waits_for_the_one_writing(tmp_path: Path) -> None:
    writers = SqliteWriters(tmp_path / "db.sqlite3-writer.lock")
    with writers:
        other = _other_writer(tmp_path / "db.sqlite3-writer.lock", hold=False)
        _wait_until_blocked(other.pid)  # the other process is blocked in the queue
        released = time.time()
    assert other.stdout is not None
    started = float(other.stdout.readline())
    assert other.wait(timeout=30) == 0
    assert started >= released


def test_this_process_waits_for_a_writer_of_another(tmp_path: Path) -> None:
    lock = tmp_path / "db.sqlite3-writer.lock"
    other = _other_writer(lock, hold=True)
    assert other.stdout is not None
    assert other.stdin is not None
    float(other.stdout.readline())  # the other holds the queue
    started: list[float] = []

    def write() -> None:
        with SqliteWriters(lock):
            started.append(time.time())

    writer = threading.Thread(target=write)
    writer.start()
    _wait_until_blocked(os.getpid())  # this process waits in the queue...
    assert started == []
    other.stdin.write("release\n")  # ...until the other lets go
    other.stdin.flush()
    other_released = float(other.stdout.readline())
    writer.join(timeout=30)
    assert other.wait(timeout=30) == 0
    assert started
    assert started[0] >= other_released


def test_threads_of_a_process_write_one_at_a_time(tmp_path: Path) -> None:
    writers = SqliteWriters(tmp_path / "w.lock")
    inside, most = 0, 0
    count = threading.Lock()

    def write() -> None:
        nonlocal inside, most
        for _ in range(20):
            with writers:
                with count:
                    inside += 1
                    most = max(most, inside)
                time.sleep(0.001)
                with count:
                    inside -= 1

    threads = [threading.Thread(target=write) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert most == 1


def test_a_failed_lock_releases_the_threads_queue(tmp_path: Path) -> None:
    writers = SqliteWriters(tmp_path / "missing-dir" / "w.lock")  # cannot be opened
    with pytest.raises(FileNotFoundError), writers:
        pass
    acquired = threading.Event()

    def other() -> None:
        with pytest.raises(FileNotFoundError), writers:
            pass
        acquired.set()

    t = threading.Thread(target=other)
    t.start()
    t.join(timeout=10)
    assert acquired.is_set()  # not left waiting on a lock the failed writer never released


def test_an_in_memory_database_queues_threads_only() -> None:
    engine = engine_for("sqlite://")
    try:
        writers = sqlite_writers(engine)
        assert writers is sqlite_writers(engine)
        with writers:
            pass
    finally:
        dispose_engines()


def test_one_engine_per_url_and_the_configured_one_among_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from app.config import get_settings

    configured = f"sqlite:///{tmp_path / 'configured.sqlite3'}"
    other = f"sqlite:///{tmp_path / 'other.sqlite3'}"
    monkeypatch.setenv("TCPCAL_DATABASE_URL", configured)
    get_settings.cache_clear()
    dispose_engines()
    try:
        assert get_engine() is engine_for(configured)
        assert engine_for(other) is engine_for(other)
        assert engine_for(other) is not get_engine()
        with session_scope(write=True, engine=engine_for(other)) as session:
            session.execute(text("CREATE TABLE t (x INTEGER)"))
            session.execute(text("INSERT INTO t VALUES (7)"))
        assert (tmp_path / "other.sqlite3-writer.lock").exists()  # the write took the queue
        with engine_for(other).connect() as conn:
            assert conn.execute(text("SELECT x FROM t")).scalar_one() == 7
        old = engine_for(other)
        dispose_engines()
        assert engine_for(other) is not old  # forgotten (and closed) by dispose_engines
    finally:
        dispose_engines()
        get_settings.cache_clear()


@pytest.mark.parametrize(("write", "locked"), [(True, True), (False, False)])
def test_a_write_transaction_holds_the_write_lock_from_its_first_statement(
    tmp_path: Path, write: bool, locked: bool
) -> None:
    """BEGIN IMMEDIATE for writes (two writers never both read a "next version number"),
    DEFERRED for reads: another connection that asks for the write lock meanwhile is refused
    only while a write transaction is open."""
    url = f"sqlite:///{tmp_path / 'begin.sqlite3'}"
    engine = engine_for(url)
    try:
        with session_scope(write=True, engine=engine) as session:
            session.execute(text("CREATE TABLE t (x INTEGER)"))
        other = sqlite3.connect(tmp_path / "begin.sqlite3", timeout=0, isolation_level=None)
        with session_scope(write=write, engine=engine) as session:
            session.execute(text("SELECT count(*) FROM t"))
            error = ""
            try:
                other.execute("BEGIN IMMEDIATE")
                other.execute("ROLLBACK")
            except sqlite3.OperationalError as exc:
                error = str(exc)
        other.close()
        assert ("database is locked" in error) is locked, error
    finally:
        dispose_engines()


def test_the_pool_opens_each_connection_once_however_many_threads_come_and_go(
    db: object,
) -> None:
    """Issue 50: SQLAlchemy's default pool kept 5 connections and closed each one above 5 as
    it came back, so the watcher's threads, each a short read transaction, opened PostgreSQL
    connections all the time (55 a second, 3 instances reading 2000 robots). Twelve threads
    taking one at once, six rounds of them: each connection is opened once."""
    from sqlalchemy import event

    from app.storage.db import POOL_SIZE

    engine = get_engine()
    engine.dispose()
    opened: list[object] = []

    def connected(conn: object, record: object) -> None:
        opened.append(conn)

    event.listen(engine, "connect", connected)
    start = threading.Barrier(12)

    def read() -> None:
        start.wait(10)
        with session_scope(write=False) as session:
            session.execute(text("SELECT 1"))
            time.sleep(0.05)  # the others hold theirs meanwhile

    try:
        for _ in range(6):
            threads = [threading.Thread(target=read) for _ in range(12)]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join(10)
    finally:
        event.remove(engine, "connect", connected)
    assert 1 <= len(opened) <= 12 <= POOL_SIZE, len(opened)  # the old pool: 47
