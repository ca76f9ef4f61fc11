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

from testbed.live_server import _free_port, http_client

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


def test_sqlite_data_directory_is_a_volume() -> None:
    env = " ".join(_instructions("ENV"))
    database = re.search(r"TCPCAL_DATABASE_URL=sqlite:///(\S+)", env)
    assert database, env
    volumes = [v.strip('[]"') for v in _instructions("VOLUME")]
    assert str(Path(database.group(1)).parent) in volumes


def test_compose_runs_two_workers_against_postgres_with_a_volume_and_health_check() -> None:
    import yaml
    from sqlalchemy.engine import make_url

    compose = yaml.safe_load((REPO / "compose.yaml").read_text())
    db, app = compose["services"]["db"], compose["services"]["tcpcal"]
    # the database keeps its data on a named volume, at the path the postgres image uses
    volume, target = db["volumes"][0].split(":")
    assert volume in compose["volumes"]
    assert target == "/var/lib/postgresql/data"
    assert "pg_isready" in " ".join(db["healthcheck"]["test"])
    # tcpcal: this repository's image, its own start command (make run's), two workers
    assert app["build"] == "."
    assert "command" not in app
    assert app["environment"]["TCPCAL_WORKERS"] == "2"
    assert "--workers ${TCPCAL_WORKERS" in _instructions("CMD")[-1]
    assert app["depends_on"]["db"]["condition"] == "service_healthy"
    url = make_url(
        app["environment"]["TCPCAL_DATABASE_URL"].replace("${TCPCAL_DB_PASSWORD:-tcpcal}", "pw")
    )
    assert url.drivername == "postgresql+psycopg"
    assert (url.host, url.port) == ("db", 5432)
    assert url.username == db["environment"]["POSTGRES_USER"]
    assert url.database == db["environment"]["POSTGRES_DB"]
    assert db["environment"]["POSTGRES_PASSWORD"] == "${TCPCAL_DB_PASSWORD:-tcpcal}"


def test_every_tcpcal_service_in_compose_gets_the_one_secret_key() -> None:
    """TCPCAL_SECRET_KEY opens the controller passwords stored in the database
    (app.security.secretbox): tcpcal needs it to store one and to deploy and reconcile
    with it, the publisher to run the MQTT re-check commands, which capture and deploy. Each
    service built from this image takes the same one from the host's environment (never a
    secret written in the file); unset, it is empty, which tcpcal reads as not set (a
    password is then refused with 422 saying so)."""
    import yaml

    services = yaml.safe_load((REPO / "compose.yaml").read_text())["services"]
    ours = {name: s for name, s in services.items() if s.get("build") == "."}
    assert set(ours) == {"tcpcal", "publisher"}
    keys = {name: s["environment"].get("TCPCAL_SECRET_KEY") for name, s in ours.items()}
    assert keys == dict.fromkeys(ours, "${TCPCAL_SECRET_KEY:-}"), keys


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
        with http_client(timeout=1) as http:  # one client: httpx.get builds one per call
            while True:
                try:
                    ready = http.get(f"http://127.0.0.1:{port}/ready")
                    break
                except httpx.HTTPError:
                    assert time.monotonic() < deadline, "server did not start"
                    time.sleep(0.2)
        assert ready.status_code == 200
        assert ready.json()["ready"] is True
    finally:
        proc.terminate()
        proc.wait(timeout=15)
