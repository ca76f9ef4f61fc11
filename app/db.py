"""Engine and sessions: SQLite (WAL, foreign keys, busy timeout) or PostgreSQL (psycopg 3).

Write transactions on SQLite start with BEGIN IMMEDIATE so that two writers never both read
the same "next version number" and then fight over the upgrade to a write lock; PostgreSQL
gets the same guarantee from SELECT ... FOR UPDATE on the tool row (see services).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from functools import lru_cache
from pathlib import Path

from sqlalchemy import Connection, Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.engine.interfaces import DBAPIConnection
from sqlalchemy.orm import Session, sessionmaker
from sqlalchemy.pool import ConnectionPoolEntry

from app.config import get_settings
from app.metrics import DB_SECONDS, SESSIONS_OPEN

SQLITE_BUSY_TIMEOUT_MS = 30_000


def _prepare_sqlite_file(url: str) -> None:
    database = make_url(url).database
    if database and database != ":memory:" and not database.startswith("file:"):
        Path(database).parent.mkdir(parents=True, exist_ok=True)


def _timed(engine: Engine) -> Engine:
    """Observe every statement's database time (tcpcal_db_statement_duration_seconds)."""

    @event.listens_for(engine, "before_cursor_execute")
    def _start(conn: Connection, *_: object) -> None:
        conn.info.setdefault("tcpcal.started", []).append(time.perf_counter())

    @event.listens_for(engine, "after_cursor_execute")
    def _stop(conn: Connection, *_: object) -> None:
        DB_SECONDS.observe(time.perf_counter() - conn.info["tcpcal.started"].pop())

    return engine


def make_engine(url: str, **pool: int) -> Engine:
    """Create an engine with the per-dialect settings this service relies on (`pool`: sizes
    of its connection pool, e.g. pool_size=1)."""
    if not url.startswith("sqlite"):
        return _timed(create_engine(url, pool_pre_ping=True, future=True, **pool))

    _prepare_sqlite_file(url)
    engine = _timed(
        create_engine(url, connect_args={"check_same_thread": False}, future=True, **pool)
    )

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn: DBAPIConnection, _record: ConnectionPoolEntry) -> None:
        # Take BEGIN out of pysqlite's hands so we can choose DEFERRED or IMMEDIATE.
        dbapi_conn.isolation_level = None
        cursor = dbapi_conn.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: Connection) -> None:
        mode = conn.get_execution_options().get("sqlite_begin", "DEFERRED")
        if mode is not None:  # None: single-statement reads (read_engine) need no transaction
            conn.exec_driver_sql(f"BEGIN {mode}")

    return engine


@lru_cache
def get_engine() -> Engine:
    """The process-wide engine for the configured database URL."""
    return make_engine(get_settings().database_url)


@lru_cache
def loop_engine() -> Engine:
    """The event loop's own connection, apart from the pool the request threads share.

    Code on the event loop (the hot active-TCP read, a solve's key check) holds a connection
    only while it runs without awaiting, so one connection is enough and the loop never waits
    for it. Taken from the threads' pool instead, the loop could wait for a connection held by
    a request that is itself waiting for the loop: under load that stalled the whole server.
    """
    return make_engine(get_settings().database_url, pool_size=1, max_overflow=0)


def dispose_engines() -> None:
    """Close every pooled connection and forget the engines (settings changed, tests)."""
    for cached in (get_engine, loop_engine):
        if cached.cache_info().currsize:
            cached().dispose()
        cached.cache_clear()


def is_sqlite(engine: Engine) -> bool:
    """True when the engine talks to SQLite."""
    return engine.dialect.name == "sqlite"


#: SQLite has one writer at a time. Its busy handler makes a waiting writer sleep in steps
#: of up to 100 ms, so 16 concurrent writes took seconds at p99; the writers of one process
#: queue here instead and each starts the moment the previous one commits. (Writers of other
#: processes still meet in SQLite's lock.)
_SQLITE_WRITER = threading.Lock()


@lru_cache(maxsize=16)
def read_engine(engine: Engine) -> Engine:
    """The engine for reads made of one statement (the hot active-TCP read): no BEGIN and no
    ROLLBACK around it (autocommit), since one SELECT sees one consistent snapshot anyway."""
    if is_sqlite(engine):
        return engine.execution_options(sqlite_begin=None)
    return engine.execution_options(isolation_level="AUTOCOMMIT")


@lru_cache(maxsize=16)
def _session_factory(engine: Engine, write: bool) -> sessionmaker[Session]:
    # Built once per engine and mode: a sessionmaker per request costs more than the query.
    bind = (
        engine.execution_options(sqlite_begin="IMMEDIATE")
        if write and is_sqlite(engine)
        else engine
    )
    return sessionmaker(bind=bind, expire_on_commit=False, autoflush=True)


@contextmanager
def session_scope(*, write: bool, engine: Engine | None = None) -> Iterator[Session]:
    """A session whose transaction commits on success and rolls back on any error."""
    engine = engine or get_engine()
    factory = _session_factory(engine, write)
    writer = _SQLITE_WRITER if write and is_sqlite(engine) else nullcontext()
    with writer, SESSIONS_OPEN.track_inprogress(), factory() as session:
        try:
            yield session
            session.commit()
        except BaseException:
            session.rollback()
            raise
