"""Test harness: every API test runs on SQLite, and on PostgreSQL when
TCPCAL_TEST_DATABASE_URL is set. Each backend gets a fresh database built by
`alembic upgrade head` (so migrations are tested); tables are emptied between tests.
A world of rows that many tests start from can be built once per backend and restored for
each of them (Api.world).
"""

from __future__ import annotations

import contextlib
import copy
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar, cast

import httpx
import pytest

from testbed.databases import TABLES as TABLES  # tests count rows of every table
from testbed.databases import Rows, delete_all, fresh_database, read_rows, write_rows
from tests.inprocess import InProcessTransport

if TYPE_CHECKING:
    from fastapi import FastAPI
    from fastapi.testclient import TestClient

PG_URL = os.environ.get("TCPCAL_TEST_DATABASE_URL")

# The CLI's rich consoles read COLUMNS once, when app.cli.client is first imported, and a run
# without a terminal (CI, xdist workers) otherwise gets 80: tables of ids and names then
# truncate the very words the CLI tests look for, depending on which test imported it first.
os.environ.setdefault("COLUMNS", "250")
BACKENDS = ["sqlite"] + (["postgresql"] if PG_URL else [])
T = TypeVar("T")

#: The one backend of a test whose subject does not go through the database's SQL, locks or
#: transactions: a network protocol, a configuration refused at start-up, a signal, a scrape.
#: Such a test starts processes (a server, a publisher, a broker) that cost seconds of CPU, and
#: the second backend would run the same code path again. PostgreSQL when the suite has it (the
#: multi-instance deployment), SQLite otherwise. Everything that reads or writes through the
#: database still runs on both (the in-process API tests, the outbox order, the publisher's
#: lock, backups, concurrency).
ONE_BACKEND = BACKENDS[-1]
#: Pins a test using `db`/`api` (or `database`) to ONE_BACKEND.
one_backend = pytest.mark.parametrize("database", [ONE_BACKEND], indirect=True)


@dataclass
class World:
    """What a world's build returned, every table's rows after it, and the API keys then."""

    value: object
    rows: Rows
    keys: dict[str, str]


@dataclass
class Database:
    backend: str
    url: str
    #: The worlds built on this database so far, by their build function (see Api.world).
    worlds: dict[object, World] = field(default_factory=dict)


@pytest.fixture(scope="session", params=BACKENDS)
def database(
    request: pytest.FixtureRequest,
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[Database]:
    """A migrated database per backend, shared by the tests of the session."""
    from app.storage.db import dispose_engines
    from app.storage.migrate import upgrade

    tmp = tmp_path_factory.mktemp("db")
    with fresh_database(request.param, tmp, PG_URL, prefix="tcpcal_test") as url:
        upgrade(url)
        try:
            yield Database(request.param, url)
        finally:
            dispose_engines()  # before the database is dropped


#: The database URL the app's engines were last made for by the `db` fixture.
_engines_for: list[str] = []


def _use_database(url: str) -> None:
    """Settings read afresh (tests monkeypatch them); engines kept while the database stays
    the same: disposing them after every test made each test connect again (a PostgreSQL
    connection, SQLite's WAL reopened), about 14 ms a test on PostgreSQL and 4 on SQLite."""
    from app.config import get_settings
    from app.storage.db import dispose_engines

    get_settings.cache_clear()
    if _engines_for != [url]:
        dispose_engines()
        _engines_for[:] = [url]


def _leave_database(url: str) -> None:
    """After a test: close the held connections (the threads that held them are gone with the
    test's app), and every engine if the test pointed the app at another database."""
    from app.config import get_settings
    from app.storage.db import HELD_CONNECTIONS, dispose_engines

    while HELD_CONNECTIONS:
        with contextlib.suppress(Exception):
            HELD_CONNECTIONS.pop().close()
    if get_settings().database_url != url:
        dispose_engines()
        _engines_for.clear()
    get_settings.cache_clear()


@pytest.fixture
def db(database: Database, monkeypatch: pytest.MonkeyPatch) -> Iterator[Database]:
    """Point the app at the test database; empty every table afterwards."""
    monkeypatch.setenv("TCPCAL_DATABASE_URL", database.url)
    monkeypatch.delenv("TCPCAL_BOOTSTRAP_ADMIN_KEY", raising=False)
    # In-process apps solve in the request's thread: a solver pool is a forkserver process
    # that imports numpy, scipy and the methods (about a second) for every test's app, and
    # the pool path has tests of its own (tests/services/test_solve_pool.py, the live servers).
    monkeypatch.setenv("TCPCAL_SOLVE_PROCESSES", "0")
    _use_database(database.url)
    yield database
    from app.storage.db import engine_for

    with engine_for(database.url).begin() as conn:
        delete_all(conn)
    _leave_database(database.url)


class Api:
    """A TestClient with a key of each scope and small helpers for common set-up."""

    def __init__(self, client: TestClient, keys: dict[str, str], database: Database) -> None:
        self.client = client
        self.keys = keys
        self.database = database
        # The helpers' requests: the same app, one crossing to its loop a request
        # (tests.inprocess); `client` is the TestClient itself, for tests that need it.
        self.http = httpx.Client(
            transport=InProcessTransport(client),
            base_url="http://testserver",
            headers={"user-agent": "testclient"},
            follow_redirects=True,
        )

    def world(self, build: Callable[[Api], T]) -> T:
        """What `build(self)` returns, and the database and keys as it left them: built by the
        first test that asks on each backend, and for every later one the rows of every table
        put back as they were then (ids, times and keys included) in place of this test's.

        For set-up that parametrized tests repeat case after case (two cells of robots, tools,
        versions and sessions: 0.3 s each time). A test then starts from the same database it
        would have built itself; whatever it changes is gone before the next. `build` must
        depend on nothing but the api (no parameter, no other fixture's value)."""
        from app.storage.db import engine_for

        engine = engine_for(self.database.url)
        world = self.database.worlds.get(build)
        if world is None:
            value = build(self)
            with engine.connect() as conn:
                rows = read_rows(conn)
            world = World(copy.deepcopy(value), rows, dict(self.keys))
            self.database.worlds[build] = world
            return value
        with engine.begin() as conn:
            delete_all(conn)
            write_rows(conn, world.rows)
        self.keys.clear()
        self.keys.update(world.keys)
        return cast("T", copy.deepcopy(world.value))

    def headers(self, scope: str = "admin", **extra: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.keys[scope]}", **extra}

    def request(self, method: str, path: str, scope: str, **kw: Any) -> httpx.Response:
        headers = {**self.headers(scope), **kw.pop("headers", {})}
        response: httpx.Response = self.http.request(method, path, headers=headers, **kw)
        return response

    def get(self, path: str, scope: str = "read", **kw: Any) -> httpx.Response:
        return self.request("GET", path, scope, **kw)

    def post(self, path: str, json: Any = None, scope: str = "admin", **kw: Any) -> httpx.Response:
        return self.request("POST", path, scope, json=json, **kw)

    def patch(self, path: str, json: Any = None, scope: str = "admin", **kw: Any) -> httpx.Response:
        return self.request("PATCH", path, scope, json=json, **kw)

    def delete(self, path: str, scope: str = "admin", **kw: Any) -> httpx.Response:
        return self.request("DELETE", path, scope, **kw)

    def robot(self, name: str = "r1", **fields: Any) -> dict[str, Any]:
        response = self.post("/v1/robots", {"name": name, **fields})
        assert response.status_code == 201, response.text
        return dict(response.json())

    def tool(self, robot_id: str, name: str = "t1", **fields: Any) -> dict[str, Any]:
        response = self.post(f"/v1/robots/{robot_id}/tools", {"name": name, **fields})
        assert response.status_code == 201, response.text
        return dict(response.json())

    def manual(self, tool_id: str, position: list[float], **fields: Any) -> dict[str, Any]:
        body = {"method": "manual", "tcp": {"position_mm": position}, **fields}
        response = self.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate")
        assert response.status_code == 201, response.text
        return dict(response.json())


#: The apps of this process, by the one setting create_app() reads (the body limit). FastAPI
#: builds an app's routes (each route's dependants and pydantic adapters) lazily, on the first
#: requests that reach its routers, and an app made for every test built them again for every
#: test: a quarter of the in-process API tests' CPU (py-spy over tests/api on both backends,
#: `_IncludedRouter.effective_candidates`). Each test still has a TestClient of its own, so the
#: app's start-up and shutdown (bootstrap key, watcher) run for it, on its own database.
_APPS: dict[int, FastAPI] = {}


def _app() -> FastAPI:
    from app.config import get_settings
    from app.main import create_app

    limit = get_settings().max_body_bytes
    if limit not in _APPS:
        _APPS[limit] = create_app()
    return _APPS[limit]


@pytest.fixture
def api(db: Database) -> Iterator[Api]:
    """The app over an in-process client, with one API key per scope."""
    import warnings

    from app.services.keys import create_key
    from app.storage.db import session_scope

    keys = {}
    with session_scope(write=True) as session:
        for scope in ("read", "calibrate", "admin"):
            keys[scope] = create_key(session, name=f"test-{scope}", scope=scope, actor=None)[1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient
    with TestClient(_app(), raise_server_exceptions=False) as client:
        api = Api(client, keys, db)
        with api.http:
            yield api
