"""Engine and sessions: SQLite (WAL, foreign keys, busy timeout) or PostgreSQL (psycopg 3).

Write transactions on SQLite start with BEGIN IMMEDIATE so that two writers never both read
the same "next version number" and then fight over the upgrade to a write lock; PostgreSQL
gets the same guarantee from SELECT ... FOR UPDATE on the tool row (see services).
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, nullcontext
from functools import lru_cache
from pathlib import Path
from typing import IO, Any, Generic, NamedTuple, TypeVar

try:
    import fcntl
except ImportError:  # Windows: no flock (see SqliteWriters)
    fcntl = None  # type: ignore[assignment]

from sqlalchemy import Connection, Engine, Insert, Select, Update, create_engine, event
from sqlalchemy.engine import URL, Dialect, make_url
from sqlalchemy.engine.interfaces import DBAPIConnection
from sqlalchemy.orm import Session, sessionmaker
from sqlalchemy.pool import ConnectionPoolEntry, NullPool, Pool, PoolProxiedConnection
from sqlalchemy.types import Float, TypeEngine

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


#: The connections an engine's pool keeps, and the most it opens: SQLAlchemy's default, 5
#: kept and 10 more opened when needed, closed each one as it came back while 5 others were
#: idle. The watcher's reading threads (up to 64) each open a short read transaction, so
#: the connections in use rose above 5 and fell many times a second: 3 instances reading
#: 2000 robots opened 55 PostgreSQL connections a second (a backend started for each).
#: Keeping all 15 opens each once; the most is the same.
POOL_SIZE = 15


def make_engine(url: str, **pool: int | type[Pool]) -> Engine:
    """Create an engine with the per-dialect settings this service relies on (`pool`: its
    connection pool's settings, e.g. pool_size=1 or poolclass=NullPool; by default
    POOL_SIZE connections, kept)."""
    if not pool and not _in_memory(url):  # an in-memory SQLite keeps one per thread
        pool = {"pool_size": POOL_SIZE, "max_overflow": 0}
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
        # On the driver's connection: through exec_driver_sql this one word cost as much
        # as the INSERT of a calibration (an execution context, events and a result).
        mode = conn.get_execution_options().get("sqlite_begin", "DEFERRED")
        driver = conn.connection.driver_connection
        assert driver is not None  # a connection in a transaction is open
        driver.execute(f"BEGIN {mode}")

    return engine


def _in_memory(url: str) -> bool:
    """Whether the URL is an in-memory SQLite database."""
    parsed = make_url(url)
    return parsed.get_backend_name() == "sqlite" and (
        parsed.database in (None, "", ":memory:") or parsed.query.get("mode") == "memory"
    )


def get_engine() -> Engine:
    """The process-wide engine for the configured database URL."""
    return engine_for(get_settings().database_url)


#: The process's engines by database URL (see engine_for).
_ENGINES: dict[str, Engine] = {}


def engine_for(url: str) -> Engine:
    """The process's engine for a database URL: the configured one, or the one a solver
    process is handed with each calibration it stores (app.services.solve_pool), whose settings were
    read when the pool started."""
    engine = _ENGINES.get(url)
    if engine is None:  # two threads may both make one: the one kept has never connected
        engine = _ENGINES.setdefault(url, make_engine(url))
    return engine


@lru_cache
def loop_engine() -> Engine:
    """The event loop's own connection, apart from the pool the request threads share.

    Code on the event loop (the hot active-TCP read, a solve's key check) holds a connection
    only while it runs without awaiting, so one connection is enough and the loop never waits
    for it. Taken from the threads' pool instead, the loop could wait for a connection held by
    a request that is itself waiting for the loop: under load that stalled the whole server.
    """
    return make_engine(get_settings().database_url, pool_size=1, max_overflow=0)


@lru_cache
def _held_engine(url: str) -> Engine:
    # No pool: each thread's held connection is its own and is really closed when dropped.
    return make_engine(url, poolclass=NullPool)


#: A column type's conversion of a value read from the driver, or of one sent to it.
Processor = Callable[[object], object]
#: Parameters as the driver takes them: positional (SQLite's qmark style) or by name.
DriverParams = tuple[object, ...] | Mapping[str, object]
#: A held read's row type: a NamedTuple whose fields are the statement's columns, in order.
RowT = TypeVar("RowT", bound=tuple[object, ...])


class HeldRead(Generic[RowT]):
    """One SELECT on a DBAPI connection that the calling thread keeps open, for the read a
    fleet of cell controllers polls (the active TCP), its rows of a NamedTuple type declared
    beside the statement.

    Through a SQLAlchemy Connection this one indexed statement cost 120 us a request (pool
    checkout, execution context, result object) against 6 us for the driver itself. Here the
    statement is compiled once per dialect and run on the driver's cursor; each column goes
    through its type's own result processor (the models' types, so JSON and UTC timestamps
    come back as everywhere else), and the row type is made of the values as they are, with
    no validation. Its fields must be the statement's selected column names, labels
    included, in order: a HeldRead over another row type raises TypeError when it is built
    (at import), so every field read that mypy checks is a column the statement returns.
    Reads only: SQLite's connections are in autocommit mode (a SELECT holds no snapshot
    after it returns) and PostgreSQL's is set to autocommit, so nothing is cached and every
    request sees the committed state. A connection that fails is dropped and the read tried
    once more on a new one (a restarted PostgreSQL). `one_or_none_in` runs the same
    statement inside a session's transaction instead (the tool's row lock of a calibration's
    write).
    """

    def __init__(self, row: type[RowT], stmt: Select[*tuple[object, ...]]) -> None:
        _check_fields(row, tuple(stmt.selected_columns.keys()))
        self._row = row
        self._stmt = stmt
        self._by_dialect: dict[str, _CompiledRead] = {}

    def _compiled(self, engine: Engine) -> _CompiledRead:
        cache = self._by_dialect
        name = engine.dialect.name
        if name not in cache:
            dialect = engine.dialect
            compiled = self._stmt.compile(dialect=dialect)
            order = list(compiled.positiontup or []) if compiled.positional else None
            processors: _Processors = [
                (i, process)
                for i, col in enumerate(self._stmt.selected_columns)
                if (process := _result_processor(col.type, dialect)) is not None
            ]
            # The values the statement holds itself (a literal compared with, a LIMIT), each
            # through its type's bind processor; a named bindparam is given by the caller.
            fixed = {
                name: _bound(bind.type.dialect_impl(dialect).bind_processor(dialect), value)
                for name, bind in compiled.binds.items()
                if (value := bind.effective_value) is not None
            }
            cache[name] = _CompiledRead(compiled.string, order, processors, fixed)
        return cache[name]

    def _connection(self, engine: Engine) -> PoolProxiedConnection:
        held: dict[URL, PoolProxiedConnection] = _HELD_BY_THREAD.__dict__.setdefault("held", {})
        conn = held.get(engine.url)
        if conn is None or conn.dbapi_connection is None:  # none yet, or closed by dispose_engines
            conn = _held_engine(engine.url.render_as_string(hide_password=False)).raw_connection()
            if not is_sqlite(engine):
                conn.dbapi_connection.autocommit = True  # type: ignore[union-attr]
            held[engine.url] = conn
            HELD_CONNECTIONS.append(conn)
        return conn

    def _drop(self, engine: Engine) -> None:
        held: dict[URL, PoolProxiedConnection] = _HELD_BY_THREAD.__dict__.get("held", {})
        conn = held.pop(engine.url, None)
        if conn is not None:
            HELD_CONNECTIONS.remove(conn)
            with contextlib.suppress(Exception):
                conn.invalidate()

    def statement(self, engine: Engine, **params: object) -> tuple[str, DriverParams]:
        """The SQL and the driver's parameters sent for `params` (for EXPLAIN in bench/)."""
        compiled = self._compiled(engine)
        return compiled.sql, _driver_params(compiled.order, {**compiled.fixed, **params})

    def one_or_none(self, engine: Engine, **params: object) -> RowT | None:
        """The statement's row for `params`, or None."""
        sql, order, processors, fixed = self._compiled(engine)
        args = _driver_params(order, {**fixed, **params})
        started = time.perf_counter()
        for attempt in (1, 2):
            try:
                rows = _fetch(self._connection(engine), sql, args)
                break
            except engine.dialect.loaded_dbapi.Error:
                self._drop(engine)
                if attempt == 2:
                    raise
        DB_SECONDS.observe(time.perf_counter() - started)
        return self._one(rows, processors)

    def one_or_none_in(self, session: Session, **params: object) -> RowT | None:
        """The same read inside a session's transaction (its connection's driver cursor)."""
        return self._one(*self._fetch_in(session, params))

    def all_in(self, session: Session, **params: object) -> list[RowT]:
        """Every row of the statement for `params`, inside a session's transaction."""
        rows, processors = self._fetch_in(session, params)
        return [self._made(row, processors) for row in rows]

    def _fetch_in(
        self, session: Session, params: Mapping[str, object]
    ) -> tuple[Sequence[Sequence[object]], _Processors]:
        conn = session.connection()
        sql, order, processors, fixed = self._compiled(conn.engine)
        started = time.perf_counter()
        args = _driver_params(order, {**fixed, **params})
        rows = _fetch(conn.connection.dbapi_connection, sql, args)
        DB_SECONDS.observe(time.perf_counter() - started)
        return rows, processors

    def _one(self, rows: Sequence[Sequence[object]], processors: _Processors) -> RowT | None:
        """The one row read, its columns through their processors, or None."""
        if not rows:
            return None
        if len(rows) > 1:
            raise RuntimeError("a held read returned more than one row")
        return self._made(rows[0], processors)

    def _made(self, row: Sequence[object], processors: _Processors) -> RowT:
        """A row of the row type, its columns through their processors."""
        values = list(row)
        for i, process in processors:
            values[i] = process(values[i])
        return tuple.__new__(self._row, values)


#: The (index, processor) of each column of a read that has a result processor.
_Processors = list[tuple[int, Processor]]


class _CompiledRead(NamedTuple):
    """A held read compiled for a dialect."""

    sql: str
    order: list[str] | None  # the order of positional parameters; None: by name
    processors: _Processors
    fixed: dict[str, object]  # the statement's own values, as sent to the driver


def _result_processor(type_: TypeEngine[Any], dialect: Dialect) -> Processor | None:
    """A column type's result processor for a held read. A float column's needs the type
    the driver reports (psycopg's numeric processor is chosen by the column's type OID, which
    a read compiled before its first execution does not have): the drivers return floats
    for the models' Float columns (double precision, REAL) themselves, so none is needed."""
    impl = type_.dialect_impl(dialect)
    if isinstance(impl, Float) and not impl.asdecimal:
        return None
    return impl.result_processor(dialect, None)


def _bound(process: Processor | None, value: object) -> object:
    return value if process is None else process(value)


def _check_fields(row: type[tuple[object, ...]], columns: tuple[str, ...]) -> None:
    """Refuse a row type whose fields are not `columns`, in order (TypeError)."""
    fields = getattr(row, "_fields", None)
    if not isinstance(fields, tuple):
        raise TypeError(f"a held read's row type is a NamedTuple, not {row.__name__}")
    if fields != columns:
        missing = [c for c in columns if c not in fields]
        extra = [f for f in fields if f not in columns]
        raise TypeError(
            f"{row.__name__}'s fields are not its statement's columns: "
            f"missing {missing}, not selected {extra}"
            + ("" if missing or extra else f", in another order than {list(columns)}")
        )


class DriverWrite:
    """An INSERT or UPDATE of the write that every calibration makes, run on the driver's
    cursor inside a session's transaction.

    Compiled once per dialect and set of parameter names; each value goes through
    its column type's bind processor (the models' types: JSON and UTC timestamps are stored
    as by every other write). Through `Connection.execute` the five statements of a
    calibration spent more in SQLAlchemy's execution contexts, events and result objects
    than in the driver (20 % of a solver process's samples under wrk). Column defaults made
    in Python are not applied: the caller gives every column that has one.
    """

    def __init__(self, stmt: Insert | Update) -> None:
        self._stmt = stmt
        self._cache: dict[tuple[str, tuple[str, ...]], _CompiledWrite] = {}

    def _compiled(self, dialect: Dialect, keys: tuple[str, ...]) -> _CompiledWrite:
        """(SQL, the order of positional parameters or None, each parameter's processor)."""
        cache = self._cache
        if (dialect.name, keys) not in cache:
            compiled = self._stmt.compile(dialect=dialect, column_keys=list(keys))
            order = list(compiled.positiontup or []) if compiled.positional else None
            processors: dict[str, Processor | None] = {
                bind.key: bind.type.dialect_impl(dialect).bind_processor(dialect)
                for bind in compiled.binds.values()
            }
            missing = set(processors) - set(keys)
            if missing:
                raise ValueError(f"parameters without values: {sorted(missing)}")
            cache[dialect.name, keys] = _CompiledWrite(compiled.string, order, processors)
        return cache[dialect.name, keys]

    def execute(self, session: Session, rows: Sequence[Mapping[str, object]]) -> None:
        """Run the statement once per row (rows of the same keys), in the session's
        transaction."""
        conn = session.connection()
        sql, order, processors = self._compiled(conn.dialect, tuple(rows[0]))
        bound: list[Mapping[str, object]] = [
            {k: (v if (p := processors[k]) is None or v is None else p(v)) for k, v in row.items()}
            for row in rows
        ]
        args: list[tuple[object, ...]] | list[Mapping[str, object]] = (
            bound if order is None else [tuple(values[k] for k in order) for values in bound]
        )
        started = time.perf_counter()
        _execute(conn.connection.dbapi_connection, sql, args)
        DB_SECONDS.observe(time.perf_counter() - started)


class _CompiledWrite(NamedTuple):
    """A driver write compiled for a dialect and set of parameter names."""

    sql: str
    order: list[str] | None  # the order of positional parameters; None: by name
    processors: dict[str, Processor | None]  # each parameter's bind processor, if any


def _fetch(
    dbapi_connection: DBAPIConnection | PoolProxiedConnection | None,
    sql: str,
    params: DriverParams,
) -> Sequence[Sequence[object]]:
    """The rows of `sql` run once on a new cursor of a driver connection."""
    assert dbapi_connection is not None  # the connection of a session's transaction is open
    cursor = dbapi_connection.cursor()
    try:
        cursor.execute(sql, params)
        return cursor.fetchall()
    finally:
        cursor.close()


def _execute(
    dbapi_connection: DBAPIConnection | None,
    sql: str,
    args: list[tuple[object, ...]] | list[Mapping[str, object]],
) -> None:
    """Run `sql` once per parameter set on a new cursor of a driver connection."""
    assert dbapi_connection is not None  # the connection of a session's transaction is open
    cursor = dbapi_connection.cursor()
    try:
        if len(args) > 1:
            cursor.executemany(sql, args)
        else:
            cursor.execute(sql, args[0])
    finally:
        cursor.close()


def _driver_params(order: list[str] | None, params: Mapping[str, object]) -> DriverParams:
    """Parameters as the driver takes them: positional in `order` (SQLite), or by name."""
    return tuple(params[k] for k in order) if order is not None else params


#: Each thread's held connections by database URL, shared by every HeldRead (one connection
#: per thread and database, however many statements are held).
_HELD_BY_THREAD = threading.local()
#: Every held connection of the process, closed by dispose_engines.
HELD_CONNECTIONS: list[PoolProxiedConnection] = []


def dispose_engines() -> None:
    """Close every pooled connection and forget the engines (settings changed, tests)."""
    while HELD_CONNECTIONS:
        with contextlib.suppress(Exception):
            HELD_CONNECTIONS.pop().close()
    _held_engine.cache_clear()
    if loop_engine.cache_info().currsize:
        loop_engine().dispose()
    loop_engine.cache_clear()
    while _ENGINES:
        _ENGINES.popitem()[1].dispose()


def is_sqlite(engine: Engine) -> bool:
    """True when the engine talks to SQLite."""
    return engine.dialect.name == "sqlite"


class SqliteWriters:
    """One writer at a time for a SQLite database file, across threads and processes.

    SQLite has one writer at a time. Its busy handler makes a waiting writer sleep in steps
    of up to 100 ms, so 16 concurrent writes took seconds at p99; writers queue here instead
    and each starts the moment the previous one commits: the threads of a process on a lock,
    and the processes (server workers, and the solver processes that store calibrations) on
    an flock of `<database>-writer.lock` next to the file. An in-memory database, or a
    platform without flock, has the threads' lock only (other processes meet in SQLite's).
    """

    def __init__(self, lock_path: Path | None) -> None:
        self._threads = threading.Lock()
        self._lock_path = lock_path if fcntl is not None else None
        self._file: tuple[int, IO[bytes]] | None = None  # (the process that opened it, file)

    def __enter__(self) -> None:
        self._threads.acquire()
        try:
            if self._lock_path is not None:
                fcntl.flock(self._fileno(), fcntl.LOCK_EX)
        except BaseException:
            self._threads.release()
            raise

    def __exit__(self, *_: object) -> None:
        try:
            if self._lock_path is not None:
                fcntl.flock(self._fileno(), fcntl.LOCK_UN)
        finally:
            self._threads.release()

    def _fileno(self) -> int:
        # Opened once per process: a forked child shares its parent's open file, and with it
        # the parent's flock, so it opens its own.
        assert self._lock_path is not None
        if self._file is None or self._file[0] != os.getpid():
            self._file = (os.getpid(), self._lock_path.open("ab"))
        return self._file[1].fileno()


_WRITERS: dict[str, SqliteWriters] = {}


def sqlite_writers(engine: Engine) -> SqliteWriters:
    """The writer queue of a SQLite engine's database."""
    database = engine.url.database or ""
    writers = _WRITERS.get(database)
    if writers is None:
        on_disk = database not in ("", ":memory:") and not database.startswith("file:")
        lock_path = Path(f"{database}-writer.lock") if on_disk else None
        writers = _WRITERS.setdefault(database, SqliteWriters(lock_path))
    return writers


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
    writer = sqlite_writers(engine) if write and is_sqlite(engine) else nullcontext()
    with writer, SESSIONS_OPEN.track_inprogress(), factory() as session:
        try:
            yield session
            session.commit()
        except BaseException:
            session.rollback()
            raise
