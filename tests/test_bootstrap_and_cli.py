"""The bootstrap admin key and `tcpcal keys create` both give working keys, stored hashed."""

from __future__ import annotations

import pytest
from sqlalchemy import select
from typer.testing import CliRunner

from app.auth import hash_key
from app.cli import cli
from app.db import session_scope
from app.models import ApiKey
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
