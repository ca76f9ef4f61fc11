"""The active-TCP read authenticates and reads in one statement, caching nothing: a revoked
key is refused by the very next request, a new activation is served at once, and every
refusal is the same problem document as on any other route."""

from __future__ import annotations

from sqlalchemy import create_engine, text

from app.storage.db import HELD_CONNECTIONS
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses
from tests.conftest import Api, Database


def test_the_hot_read_sees_revocations_and_activations_at_once(api: Api) -> None:
    tool = api.tool(api.robot("kr")["id"], slot=2)
    tid = tool["id"]
    for z in (150, 151):
        api.post(
            f"/v1/tools/{tid}/calibrations",
            json={"method": "manual", "tcp": {"position_mm": [0, 0, z]}},
        )
    created = api.post("/v1/keys", json={"name": "cell-7", "scope": "read"}).json()
    reader = {"Authorization": f"Bearer {created['key']}"}
    first = api.client.get(f"/v1/tools/{tid}/tcp", headers=reader)
    assert first.status_code == 200
    assert first.json()["tcp"]["position_mm"] == [0.0, 0.0, 151.0]

    api.post(f"/v1/tools/{tid}/versions/1/activate")
    again = api.client.get(
        f"/v1/tools/{tid}/tcp", headers={**reader, "If-None-Match": first.headers["etag"]}
    )
    assert again.status_code == 200  # not 304: the activation is served by the next read
    assert again.json()["version"] == 1

    assert api.delete(f"/v1/keys/{created['id']}").status_code == 204
    revoked = api.client.get(f"/v1/tools/{tid}/tcp", headers=reader)
    assert revoked.status_code == 401
    assert revoked.headers["content-type"].startswith("application/problem+json")
    assert "revoked" in revoked.json()["detail"]

    assert api.client.get(f"/v1/tools/{tid}/tcp").status_code == 401  # no header
    bad = {"Authorization": "Bearer not-a-key"}
    assert api.client.get("/v1/tools/nope/tcp", headers=bad).status_code == 401  # key first
    assert api.get("/v1/tools/00000000-0000-0000-0000-000000000000/tcp").status_code == 404
    fresh = api.tool(api.robot("kr2")["id"])
    none = api.get(f"/v1/tools/{fresh['id']}/tcp")
    assert none.status_code == 404
    assert none.json()["type"].endswith("/no-active-version")
    api.delete(f"/v1/tools/{tid}")
    archived = api.get(f"/v1/tools/{tid}/tcp")
    assert archived.status_code == 404
    assert archived.json()["type"].endswith("/archived")


def _tool_with_tcp(api: Api) -> str:
    tid: str = api.tool(api.robot("held")["id"], slot=1)["id"]
    api.manual(tid, [0, 0, 150])
    return tid


def test_the_held_connection_keeps_no_transaction_open(api: Api, db: Database) -> None:
    """A SELECT on the held connection leaves no snapshot behind. PostgreSQL: no session of
    the database stays 'idle in transaction' (it would hold back vacuum and TRUNCATE).
    SQLite: a checkpoint can empty the whole write-ahead log (a reader's snapshot pins it)."""
    tid = _tool_with_tcp(api)
    for _ in range(3):
        assert api.get(f"/v1/tools/{tid}/tcp").status_code == 200
    api.manual(tid, [0, 0, 151])  # something in the log
    assert api.get(f"/v1/tools/{tid}/tcp").json()["version"] == 2
    with create_engine(db.url).connect() as conn:
        if db.backend == "postgresql":
            stuck = conn.execute(
                text(
                    "SELECT count(*) FROM pg_stat_activity WHERE datname = current_database() "
                    "AND state LIKE 'idle in transaction%'"
                )
            ).scalar_one()
            assert stuck == 0
        else:
            busy, _, _ = conn.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)").one()
            assert busy == 0


def test_the_hot_read_survives_a_dropped_connection(api: Api, db: Database) -> None:
    """The held connection dropped under it (PostgreSQL restarted: every other session of
    the database terminated; SQLite: the handle closed): the next read is answered on a new
    connection, not with a 500."""
    tid = _tool_with_tcp(api)
    assert api.get(f"/v1/tools/{tid}/tcp").status_code == 200
    if db.backend == "postgresql":
        with create_engine(db.url, isolation_level="AUTOCOMMIT").connect() as conn:
            killed = conn.execute(
                text(
                    "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity "
                    "WHERE datname = current_database() AND pid <> pg_backend_pid()"
                )
            ).scalar_one()
        assert killed >= 1
    else:
        assert HELD_CONNECTIONS, "the read above should hold a connection"
        for held in HELD_CONNECTIONS:
            assert held.dbapi_connection is not None
            held.dbapi_connection.close()
    answer = api.get(f"/v1/tools/{tid}/tcp")
    assert answer.status_code == 200, answer.text
    assert answer.json()["tcp"]["position_mm"] == [0.0, 0.0, 150.0]


def test_the_held_reads_share_one_connection_per_thread(api: Api) -> None:
    """The TCP read and /v1/solve's key check both run on the event loop: one connection."""
    tid = _tool_with_tcp(api)
    assert api.get(f"/v1/tools/{tid}/tcp").status_code == 200
    body = {
        "method": "xyz_npoint",
        "format": "xyz_wxyz",
        "poses": as_poses(simulate_touches(6, seed=3)),
    }
    assert api.post("/v1/solve", body, scope="read").status_code == 200
    assert len(HELD_CONNECTIONS) == 1


def test_the_hot_read_after_the_engines_were_disposed(api: Api) -> None:
    """dispose_engines closes the held connections (settings changed, tests): the next read
    takes a new one instead of failing on the closed one."""
    from app.storage.db import dispose_engines

    tid = _tool_with_tcp(api)
    assert api.get(f"/v1/tools/{tid}/tcp").status_code == 200
    dispose_engines()
    assert api.get(f"/v1/tools/{tid}/tcp").status_code == 200
