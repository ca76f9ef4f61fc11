"""Test harness: every API test runs on SQLite, and on PostgreSQL when
TCPCAL_TEST_DATABASE_URL is set. Each backend gets a fresh database built by
`alembic upgrade head` (so migrations are tested); tables are emptied between tests.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import httpx
import pytest
from sqlalchemy import text

from tests.databases import fresh_database

if TYPE_CHECKING:
    from fastapi.testclient import TestClient

PG_URL = os.environ.get("TCPCAL_TEST_DATABASE_URL")

# The CLI's rich consoles read COLUMNS once, when app.client is first imported, and a run
# without a terminal (CI, xdist workers) otherwise gets 80: tables of ids and names then
# truncate the very words the CLI tests look for, depending on which test imported it first.
os.environ.setdefault("COLUMNS", "250")
BACKENDS = ["sqlite"] + (["postgresql"] if PG_URL else [])

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


def _reset_app_caches() -> None:
    from app.config import get_settings
    from app.db import dispose_engines

    dispose_engines()
    get_settings.cache_clear()


@dataclass
class Database:
    backend: str
    url: str


@pytest.fixture(scope="session", params=BACKENDS)
def database(
    request: pytest.FixtureRequest,
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[Database]:
    """A migrated database per backend, shared by the tests of the session."""
    from app.migrate import upgrade

    tmp = tmp_path_factory.mktemp("db")
    with fresh_database(request.param, tmp, PG_URL, prefix="tcpcal_test") as url:
        upgrade(url)
        yield Database(request.param, url)


TABLES = (
    "deployments",
    "tool_controller_states",
    "robot_controllers",
    "outbox",
    "guided_sessions",
    "audit_events",
    "idempotency_records",
    "activations",
    "tcp_versions",
    "reference_points",
    "laser_devices",
    "calibrations",
    "tools",
    "robots",
    "api_keys",
)


@pytest.fixture
def db(database: Database, monkeypatch: pytest.MonkeyPatch) -> Iterator[Database]:
    """Point the app at the test database; empty every table afterwards."""
    monkeypatch.setenv("TCPCAL_DATABASE_URL", database.url)
    monkeypatch.delenv("TCPCAL_BOOTSTRAP_ADMIN_KEY", raising=False)
    # In-process apps solve in the request's thread: a solver pool is a forkserver process
    # that imports numpy, scipy and the methods (about a second) for every test's app, and
    # the pool path has tests of its own (tests/test_solve_pool.py, the live servers).
    monkeypatch.setenv("TCPCAL_SOLVE_PROCESSES", "0")
    _reset_app_caches()
    yield database
    from app.db import get_engine

    engine = get_engine()
    # DELETE, children first, on both backends: PostgreSQL's TRUNCATE of 15 tables took about
    # 0.5 s a test (it rewrites every table and its indexes), DELETE of a few rows milliseconds.
    with engine.begin() as conn:
        for table in TABLES:
            conn.execute(text(f"DELETE FROM {table}"))
    _reset_app_caches()


class Api:
    """A TestClient with a key of each scope and small helpers for common set-up."""

    def __init__(self, client: TestClient, keys: dict[str, str]) -> None:
        self.client = client
        self.keys = keys

    def headers(self, scope: str = "admin", **extra: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.keys[scope]}", **extra}

    def request(self, method: str, path: str, scope: str, **kw: Any) -> httpx.Response:
        headers = {**self.headers(scope), **kw.pop("headers", {})}
        response: httpx.Response = self.client.request(method, path, headers=headers, **kw)
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


@pytest.fixture
def api(db: Database) -> Iterator[Api]:
    """The app over an in-process client, with one API key per scope."""
    import warnings

    from app.db import session_scope
    from app.main import create_app
    from app.services.keys import create_key

    keys = {}
    with session_scope(write=True) as session:
        for scope in ("read", "calibrate", "admin"):
            keys[scope] = create_key(session, name=f"test-{scope}", scope=scope, actor=None)[1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient
    with TestClient(create_app(), raise_server_exceptions=False) as client:
        yield Api(client, keys)
