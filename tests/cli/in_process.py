"""The CLI pointed at the in-process app: what the CLI tests share."""

from __future__ import annotations

import httpx
import pytest
from typer.testing import CliRunner

from app.cli import http as client_http
from tests.conftest import Api


def cli_as(scope: str, api: Api, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    """A runner whose commands talk to the in-process app (its test transport) with a key
    of `scope`, on a console wide enough that no table truncates a word a test looks for."""

    def http() -> httpx.Client:
        return httpx.Client(
            transport=api.client._transport,
            base_url="http://testserver",
            headers=api.headers(scope),
        )

    monkeypatch.setattr(client_http, "connect", http)
    monkeypatch.setenv("COLUMNS", "250")
    return CliRunner()
