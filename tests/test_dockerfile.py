"""The Dockerfile, checked without a Docker engine: what it copies exists, it runs as a
non-root user, and its start command is `make run`'s (migrate, then serve the same app).
The last test performs the image's install and start steps outside Docker."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from tests.live.server import _free_port

REPO = Path(__file__).resolve().parents[1]
DOCKERFILE = (REPO / "Dockerfile").read_text()


def _instructions(name: str) -> list[str]:
    joined = DOCKERFILE.replace("\\\n", " ")
    return [
        line.split(None, 1)[1]
        for line in joined.splitlines()
        if line.strip().upper().startswith(name + " ")
    ]


def test_base_is_slim_python_matching_pyproject() -> None:
    bases = _instructions("FROM")
    assert bases
    assert all(re.match(r"python:3\.11-slim\b", b) for b in bases), bases
    assert 'requires-python = ">=3.11"' in (REPO / "pyproject.toml").read_text()


def test_copied_paths_exist() -> None:
    for copy in _instructions("COPY"):
        if copy.startswith("--from"):
            continue
        *sources, _dest = copy.split()
        for source in sources:
            assert (REPO / source).exists(), f"Dockerfile copies missing {source}"


def test_runs_as_non_root() -> None:
    users = _instructions("USER")
    assert users
    assert users[-1] not in {"root", "0"}


def test_start_command_is_make_runs_migrate_then_serve() -> None:
    cmd = _instructions("CMD")[-1]
    assert "tcpcal db upgrade &&" in cmd
    assert "tcpcal serve" in cmd
    makefile = (REPO / "Makefile").read_text()
    assert "$(BIN)/tcpcal db upgrade" in makefile
    assert "$(BIN)/tcpcal serve" in makefile


def test_dockerignore_keeps_local_state_out() -> None:
    ignored = (REPO / ".dockerignore").read_text().split()
    assert {".venv", "var", ".git"} <= set(ignored)


@pytest.mark.live
def test_image_steps_run_outside_docker(tmp_path: Path) -> None:
    """What the image does at start, from a copy holding only what the Dockerfile copies."""
    work = tmp_path / "srv"
    work.mkdir()
    shutil.copy(REPO / "alembic.ini", work)
    shutil.copytree(REPO / "migrations", work / "migrations")
    tcpcal = str(Path(sys.executable).parent / "tcpcal")
    port = _free_port()
    env = {**os.environ, "TCPCAL_DATABASE_URL": f"sqlite:///{tmp_path / 'img.sqlite3'}"}
    subprocess.run([tcpcal, "db", "upgrade"], cwd=work, env=env, check=True, capture_output=True)
    proc = subprocess.Popen(
        [tcpcal, "serve", "--host", "127.0.0.1", "--port", str(port)],
        cwd=work,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 30
        while True:
            try:
                ready = httpx.get(f"http://127.0.0.1:{port}/ready", timeout=1)
                break
            except httpx.HTTPError:
                assert time.monotonic() < deadline, "server did not start"
                time.sleep(0.2)
        assert ready.status_code == 200
        assert ready.json()["ready"] is True
    finally:
        proc.terminate()
        proc.wait(timeout=15)
