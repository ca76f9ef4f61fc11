"""Migrations: an empty database goes to head, matches the models exactly, and back to base."""

from __future__ import annotations

import json
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect, text

from app.storage.db import make_engine
from app.storage.migrate import downgrade, head_revision, upgrade
from app.storage.models import Base
from testbed.databases import fresh_database
from tests.conftest import BACKENDS, PG_URL


@pytest.fixture(params=BACKENDS)
def empty_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    with fresh_database(request.param, tmp_path, PG_URL, prefix="tcpcal_mig") as url:
        yield url


def test_upgrade_matches_models_and_downgrades(empty_url: str) -> None:
    upgrade(empty_url)
    engine = make_engine(empty_url)
    try:
        with engine.connect() as conn:
            context = MigrationContext.configure(conn, opts={"compare_type": True})
            assert context.get_current_revision() == head_revision()
            diff = compare_metadata(context, Base.metadata)
        assert diff == [], f"models and migrations differ: {diff}"
        tables = set(inspect(engine).get_table_names())
        assert set(Base.metadata.tables) <= tables
    finally:
        engine.dispose()

    downgrade(empty_url, "base")
    engine = make_engine(empty_url)
    try:
        assert set(inspect(engine).get_table_names()) <= {"alembic_version"}
    finally:
        engine.dispose()


def test_ready_is_false_until_migrated(empty_url: str, monkeypatch: pytest.MonkeyPatch) -> None:
    from fastapi.testclient import TestClient

    from app.config import get_settings
    from app.main import create_app
    from app.storage.db import dispose_engines

    monkeypatch.setenv("TCPCAL_DATABASE_URL", empty_url)
    get_settings.cache_clear()
    dispose_engines()
    try:
        with TestClient(create_app()) as client:
            before = client.get("/ready")
            assert before.status_code == 503
            assert before.json()["revision"] is None
            upgrade(empty_url)
            after = client.get("/ready")
            assert after.status_code == 200
            assert after.json()["ready"] is True
    finally:
        dispose_engines()
        get_settings.cache_clear()


#: The revision before deployments told a failure before the write from one after it.
BEFORE_DEPLOYMENT_TRUTH = "2026_11_24_audit_scoped_keys"


def test_old_failed_deployments_are_mapped_honestly(empty_url: str) -> None:
    """'failed' meant either: a refusal becomes not_written, anything else unverified (the
    old code could not tell), and its "nothing was written" no longer claims so."""
    upgrade(empty_url, BEFORE_DEPLOYMENT_TRUTH)
    engine = make_engine(empty_url)
    now = datetime.now(UTC)
    refused = {"type": "controller-refused", "detail": "the controller refused: no", "x": 1}
    lost = {
        "type": "controller-unreachable",
        "detail": "the controller at 127.0.0.1:7000 could not be reached within 5 s: reset; "
        "nothing was written",
    }
    try:
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO robots (id, name, created_at, updated_at) "
                    "VALUES ('r', 'r', :t, :t)"
                ),
                {"t": now},
            )
            conn.execute(
                text(
                    "INSERT INTO tools (id, robot_id, name, tolerance, last_version, revision, "
                    "created_at, updated_at) VALUES ('t', 'r', 't', '{}', 1, 1, :t, :t)"
                ),
                {"t": now},
            )
            for status, error in (("failed", refused), ("failed", lost), ("verified", None)):
                conn.execute(
                    text(
                        "INSERT INTO deployments (tool_id, robot_id, version, protocol, target, "
                        "status, error, actor, created_at) VALUES ('t', 'r', 1, 'kuka_kvp', "
                        "'$TOOL_DATA[3]', :s, :e, 'a', :t)"
                    ),
                    {"s": status, "e": None if error is None else json.dumps(error), "t": now},
                )
    finally:
        engine.dispose()
    upgrade(empty_url)
    engine = make_engine(empty_url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(
                text("SELECT status, error, reason, settled FROM deployments ORDER BY id")
            ).all()
    finally:
        engine.dispose()
    errors: list[Any] = [e if not isinstance(e, str) else json.loads(e) for _, e, _, _ in rows]
    assert [r[0] for r in rows] == ["not_written", "unverified", "verified"]
    assert errors[0] == refused
    assert errors[1]["type"] == "controller-unreachable"
    assert "nothing was written" not in errors[1]["detail"]
    assert errors[1]["detail"].startswith("the controller at 127.0.0.1:7000 could not be reached")
    assert "may have held this version or what it held before" in errors[1]["detail"]
    assert errors[2] is None
    assert [(r[2], r[3]) for r in rows] == [(None, None)] * 3
    downgrade(empty_url, BEFORE_DEPLOYMENT_TRUTH)
    engine = make_engine(empty_url)
    try:
        with engine.connect() as conn:
            statuses = conn.execute(text("SELECT status FROM deployments ORDER BY id")).scalars()
            assert list(statuses) == ["failed", "failed", "verified"]
    finally:
        engine.dispose()


BEFORE_MAX_CORRECTION = "2026_11_27_live_tools"


def _tolerances(url: str) -> dict[str, Any]:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(text("SELECT id, tolerance FROM tools ORDER BY id")).all()
    finally:
        engine.dispose()
    return {i: t if not isinstance(t, str) else json.loads(t) for i, t in rows}


def test_stored_tolerances_gain_max_correction_mm(empty_url: str) -> None:
    """Issue 41: every stored tolerance gets the default 2.0 mm, what a re-check applies;
    a downgrade takes it out again."""
    upgrade(empty_url, BEFORE_MAX_CORRECTION)
    engine = make_engine(empty_url)
    now = datetime.now(UTC)
    try:
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO robots (id, name, created_at, updated_at) "
                    "VALUES ('r', 'r', :t, :t)"
                ),
                {"t": now},
            )
            for tool_id, tolerance in (("a", {}), ("b", {"check_mm": 0.4})):
                conn.execute(
                    text(
                        "INSERT INTO tools (id, robot_id, name, tolerance, last_version, "
                        "revision, created_at, updated_at) VALUES (:i, 'r', :i, :tol, 0, 1, "
                        ":t, :t)"
                    ),
                    {"i": tool_id, "tol": json.dumps(tolerance), "t": now},
                )
    finally:
        engine.dispose()
    upgrade(empty_url)
    assert _tolerances(empty_url) == {
        "a": {"max_correction_mm": 2.0},
        "b": {"check_mm": 0.4, "max_correction_mm": 2.0},
    }
    downgrade(empty_url, BEFORE_MAX_CORRECTION)
    assert _tolerances(empty_url) == {"a": {}, "b": {"check_mm": 0.4}}


BEFORE_DEPLOYMENT_SCOPE = "2026_11_28_controller_ports"


def test_stored_deployments_gain_their_protocols_scope(empty_url: str) -> None:
    """Contract v1.3: each deployment says where it holds, set for the existing rows by
    their protocol (UR and Techman live, the others stored); a downgrade drops it."""
    upgrade(empty_url, BEFORE_DEPLOYMENT_SCOPE)
    engine = make_engine(empty_url)
    now = datetime.now(UTC)
    protocols = ["kuka_kvp", "fanuc_rmi", "abb_rws2", "yaskawa_hses", "techman", "ur_rtde"]
    try:
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO robots (id, name, created_at, updated_at) "
                    "VALUES ('r', 'r', :t, :t)"
                ),
                {"t": now},
            )
            conn.execute(
                text(
                    "INSERT INTO tools (id, robot_id, name, tolerance, last_version, revision, "
                    "created_at, updated_at) VALUES ('t', 'r', 't', '{}', 1, 1, :t, :t)"
                ),
                {"t": now},
            )
            for protocol in protocols:
                conn.execute(
                    text(
                        "INSERT INTO deployments (tool_id, robot_id, version, protocol, target, "
                        "status, actor, created_at) VALUES ('t', 'r', 1, :p, 'x', 'verified', "
                        "'a', :t)"
                    ),
                    {"p": protocol, "t": now},
                )
    finally:
        engine.dispose()
    upgrade(empty_url)
    engine = make_engine(empty_url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(text("SELECT protocol, scope FROM deployments ORDER BY id")).all()
    finally:
        engine.dispose()
    assert [tuple(r) for r in rows] == [
        ("kuka_kvp", "stored"),
        ("fanuc_rmi", "stored"),
        ("abb_rws2", "stored"),
        ("yaskawa_hses", "stored"),
        ("techman", "live"),
        ("ur_rtde", "live"),
    ]
    downgrade(empty_url, BEFORE_DEPLOYMENT_SCOPE)
    engine = make_engine(empty_url)
    try:
        columns = {c["name"] for c in inspect(engine).get_columns("deployments")}
    finally:
        engine.dispose()
    assert "scope" not in columns


def test_a_controller_of_several_services_keeps_its_main_port_on_downgrade(
    empty_url: str,
) -> None:
    """Downgraded below `ports`, such a controller's `port` is its main service's (the
    older code, which knows no such protocol, then refuses it as it would any other)."""
    upgrade(empty_url)
    engine = make_engine(empty_url)
    now = datetime.now(UTC)
    try:
        with engine.begin() as conn:
            for robot_id, protocol, port, ports in (
                ("a", "kuka_kvp", 7000, None),
                ("b", "techman", None, {"listen_node": 6890, "ethernet_slave": 6891}),
            ):
                conn.execute(
                    text(
                        "INSERT INTO robots (id, name, created_at, updated_at) "
                        "VALUES (:r, :r, :t, :t)"
                    ),
                    {"r": robot_id, "t": now},
                )
                conn.execute(
                    text(
                        "INSERT INTO robot_controllers (robot_id, protocol, host, port, ports, "
                        "timeout_s, tls_verify, created_at, updated_at) VALUES (:r, :p, 'h', "
                        ":port, :ports, 5, true, :t, :t)"
                    ),
                    {
                        "r": robot_id,
                        "p": protocol,
                        "port": port,
                        "ports": None if ports is None else json.dumps(ports),
                        "t": now,
                    },
                )
    finally:
        engine.dispose()
    downgrade(empty_url, "2026_11_27_max_correction")
    engine = make_engine(empty_url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(
                text("SELECT robot_id, port FROM robot_controllers ORDER BY robot_id")
            ).all()
    finally:
        engine.dispose()
    assert [tuple(r) for r in rows] == [("a", 7000), ("b", 6890)]
