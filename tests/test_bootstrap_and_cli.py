"""The bootstrap admin key and `tcpcal keys create` both give working keys, stored hashed."""

from __future__ import annotations

from pathlib import Path

import pytest
from sqlalchemy import select
from typer.testing import CliRunner

from app.cli import cli
from app.security.auth import hash_key
from app.storage.db import session_scope
from app.storage.models import ApiKey
from tests.conftest import Database


def test_bootstrap_key_is_admin_and_stored_hashed(
    db: Database, monkeypatch: pytest.MonkeyPatch
) -> None:
    from fastapi.testclient import TestClient

    from app.config import get_settings
    from app.main import create_app

    secret = "bootstrap-secret-for-tests-0123456789"
    monkeypatch.setenv("TCPCAL_BOOTSTRAP_ADMIN_KEY", secret)
    get_settings.cache_clear()
    for _ in range(2):  # a restart must not duplicate it
        with TestClient(create_app()) as client:
            response = client.post(
                "/v1/robots", json={"name": "boot"}, headers={"Authorization": f"Bearer {secret}"}
            )
            assert response.status_code in (201, 409)
    with session_scope(write=False) as session:
        rows = session.scalars(select(ApiKey).where(ApiKey.name == "bootstrap-admin")).all()
        assert len(rows) == 1
        assert rows[0].scope == "admin"
        assert rows[0].key_hash == hash_key(secret)
        assert secret not in (rows[0].prefix + rows[0].key_hash)


def test_cli_keys_create_prints_a_working_key(db: Database) -> None:
    from fastapi.testclient import TestClient

    from app.main import create_app

    result = CliRunner().invoke(cli, ["keys", "create", "--scope", "read", "--name", "cell-12"])
    assert result.exit_code == 0, result.output
    key = next(line.split()[-1] for line in result.output.splitlines() if line.startswith("key:"))
    with TestClient(create_app()) as client:
        headers = {"Authorization": f"Bearer {key}"}
        assert client.get("/v1/robots", headers=headers).status_code == 200
        assert client.post("/v1/robots", json={"name": "x"}, headers=headers).status_code == 403
    bad = CliRunner().invoke(cli, ["keys", "create", "--scope", "root", "--name", "x"])
    assert bad.exit_code == 2
    reserved = CliRunner().invoke(cli, ["keys", "create", "--scope", "read", "--name", "me"])
    assert reserved.exit_code == 2, reserved.output
    assert "name: Value error, 'me' is a reserved word" in reserved.output


def _key_of(output: str) -> str:
    return next(line.split()[-1] for line in output.splitlines() if line.startswith("key:"))


def _id_of(output: str) -> str:
    return next(line.split()[-1] for line in output.splitlines() if line.startswith("id:"))


def test_cli_keys_list_revoke_rotate(db: Database) -> None:
    from fastapi.testclient import TestClient

    from app.main import create_app
    from app.storage.models import AuditEvent

    runner = CliRunner()
    made = runner.invoke(cli, ["keys", "create", "--scope", "calibrate", "--name", "cell-3"])
    first_id, first_key = _id_of(made.output), _key_of(made.output)

    rotated = runner.invoke(cli, ["keys", "rotate", first_id])
    assert rotated.exit_code == 0, rotated.output
    second_id, second_key = _id_of(rotated.output), _key_of(rotated.output)
    assert second_id != first_id
    assert f"revoked {first_id}" in rotated.output

    listing = runner.invoke(cli, ["keys", "list"])
    lines = {line.split()[0]: line for line in listing.output.splitlines()}
    assert "revoked" in lines[first_id]
    assert "active" in lines[second_id]
    assert "calibrate" in lines[second_id]
    assert "cell-3" in lines[second_id]
    assert first_key not in listing.output
    assert second_key not in listing.output

    with TestClient(create_app()) as client:
        assert (
            client.get("/v1/robots", headers={"Authorization": f"Bearer {first_key}"}).status_code
            == 401
        )
        assert (
            client.get("/v1/robots", headers={"Authorization": f"Bearer {second_key}"}).status_code
            == 200
        )
        revoked = runner.invoke(cli, ["keys", "revoke", second_id])
        assert revoked.exit_code == 0, revoked.output
        assert (
            client.get("/v1/robots", headers={"Authorization": f"Bearer {second_key}"}).status_code
            == 401
        )

    again = runner.invoke(cli, ["keys", "revoke", second_id])
    assert again.exit_code == 1
    assert "already revoked" in again.output
    unknown = runner.invoke(cli, ["keys", "rotate", "no-such-key"])
    assert unknown.exit_code == 1
    with session_scope(write=False) as session:
        actions = [e.action for e in session.scalars(select(AuditEvent).order_by(AuditEvent.at))]
        actors = {e.actor for e in session.scalars(select(AuditEvent))}
    assert actions.count("key.revoke") == 2
    assert actions.count("key.create") == 2
    assert all(a.startswith("cli:") for a in actors)


@pytest.mark.parametrize("command", [["keys", "create", "--scope", "admin", "--name", "ops"],
                                     ["keys", "list"]])  # fmt: skip
def test_keys_outside_the_project_directory_say_which_database_and_create_none(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: list[str]
) -> None:
    from app.config import get_settings

    monkeypatch.delenv("TCPCAL_DATABASE_URL", raising=False)
    monkeypatch.chdir(tmp_path)
    get_settings.cache_clear()
    try:
        result = CliRunner().invoke(cli, command)
        assert result.exit_code == 2, result.output
        said = " ".join(result.output.split())
        assert f"no tcpcal database at {tmp_path.resolve()}/var/tcpcal.sqlite3" in said
        assert "set TCPCAL_DATABASE_URL to the server's database" in said
        assert "Traceback" not in result.output
        assert not (tmp_path / "var").exists()  # no empty SQLite file left behind

        (tmp_path / "empty.sqlite3").touch()  # a database never migrated
        monkeypatch.setenv("TCPCAL_DATABASE_URL", "sqlite:///empty.sqlite3")
        get_settings.cache_clear()
        empty = CliRunner().invoke(cli, command)
        assert empty.exit_code == 2, empty.output
        assert "has no tcpcal tables: migrate it with `tcpcal db upgrade`" in " ".join(
            empty.output.split()
        )
    finally:
        get_settings.cache_clear()
