"""Migrations: an empty database goes to head, matches the models exactly, and back to base."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect

from app.db import make_engine
from app.migrate import downgrade, head_revision, upgrade
from app.models import Base
from tests.conftest import BACKENDS, PG_URL
from tests.databases import fresh_database


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
    from app.db import dispose_engines
    from app.main import create_app

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
