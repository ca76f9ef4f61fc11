"""`tcpcal db restore` refuses a database another process has open: it replaced the content
under a running server without a word."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text
from typer.testing import CliRunner

from app.cli import cli
from app.storage.migrate import upgrade
from testbed.databases import fresh_database
from tests.conftest import BACKENDS, PG_URL

#: Another process with the database open as a server has it (the app's engine: SQLite in WAL).
HOLD = """
import sys, time
from sqlalchemy import text
from app.storage.db import make_engine
engine = make_engine(sys.argv[1])
with engine.connect() as conn:
    conn.execute(text("SELECT 1")).all()
    print("open", flush=True)
    time.sleep(60)
"""


@pytest.fixture(params=BACKENDS)
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    with fresh_database(request.param, tmp_path, PG_URL, prefix="tcpcal_restore") as url:
        upgrade(url)
        yield url


def _run(url: str, *args: str, monkeypatch: pytest.MonkeyPatch) -> tuple[int, str]:
    from app.config import get_settings

    monkeypatch.setenv("TCPCAL_DATABASE_URL", url)
    get_settings.cache_clear()
    try:
        result = CliRunner().invoke(cli, ["db", *args])
    finally:
        get_settings.cache_clear()
    return result.exit_code, result.output


def _robot_names(url: str) -> list[str]:
    engine = create_engine(url)
    try:
        with engine.connect() as conn:
            return [r[0] for r in conn.execute(text("SELECT name FROM robots ORDER BY name"))]
    finally:
        engine.dispose()


def _add_robot(url: str, name: str) -> None:
    engine = create_engine(url)
    try:
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO robots (id, name, created_at, updated_at) "
                    "VALUES (:id, :name, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP)"
                ),
                {"id": name, "name": name},
            )
    finally:
        engine.dispose()


def test_restore_refuses_while_another_process_has_the_database_open(
    database_url: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _add_robot(database_url, "kept")
    backup = tmp_path / "backup.bin"
    code, output = _run(database_url, "backup", str(backup), monkeypatch=monkeypatch)
    assert code == 0, output
    _add_robot(database_url, "later")

    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, database_url], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None
        assert holder.stdout.readline().strip() == "open"
        code, output = _run(database_url, "restore", str(backup), monkeypatch=monkeypatch)
        assert code == 1
        assert "open in" in output
        assert "stop every server" in output
        assert "--force" in output
        assert _robot_names(database_url) == ["kept", "later"]  # nothing restored
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.2)  # PostgreSQL ends the killed client's session a moment later

    code, output = _run(database_url, "restore", str(backup), monkeypatch=monkeypatch)
    assert code == 0, output
    assert _robot_names(database_url) == ["kept"]
