"""Start `tcpcal serve` as a real multi-worker uvicorn on a loopback port, for live tests."""

from __future__ import annotations

import os
import socket
import ssl
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import httpx

from app.services.keys import create_key
from app.storage.db import make_engine, session_scope
from app.storage.migrate import upgrade
from testbed.databases import fresh_database

__all__ = ["LiveServer", "fresh_database", "http_client", "live_server"]

REPO = Path(__file__).resolve().parents[1]

#: httpx builds a TLS context and loads the CA bundle for every Client it is not given one,
#: even for http:// on loopback: 30-50 ms of CPU per client, and the live tests make hundreds
#: (a client per thread, per poll), CPU their servers needed.
TLS = ssl.create_default_context()


def http_client(base_url: str = "", **kw: Any) -> httpx.Client:
    """An httpx client on the shared TLS context."""
    return httpx.Client(base_url=base_url, verify=TLS, **kw)


@dataclass
class LiveServer:
    url: str
    admin_key: str
    process: subprocess.Popen[bytes] | None = None

    def client(self) -> httpx.Client:
        return http_client(
            self.url, timeout=60, headers={"Authorization": f"Bearer {self.admin_key}"}
        )


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _wait_until_ready(proc: subprocess.Popen[bytes], url: str, output: IO[bytes]) -> None:
    """Poll /ready through one client (`httpx.get` builds a client, and its TLS context, on every
    call)."""
    deadline = time.monotonic() + 60
    with http_client(timeout=1) as http:
        while True:
            if proc.poll() is not None:
                output.seek(0)
                raise RuntimeError(f"server exited early:\n{output.read().decode()}")
            try:
                if http.get(f"{url}/ready").status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError("server did not become ready within 60 s")
            time.sleep(0.1)


@contextmanager
def live_server(
    database_url: str,
    *,
    workers: int = 2,
    solvers: int = 1,
    log: IO[bytes] | None = None,
    process_group: bool = False,
) -> Iterator[LiveServer]:
    """Migrate, create an admin key, serve with `tcpcal serve --workers N`, stop afterwards.
    With `process_group` the server leads a process group of its own, which a test can signal
    as a terminal's Ctrl-C does (every process of the group: workers, solvers, forkservers).

    `solvers` is each worker's TCPCAL_SOLVE_PROCESSES. One keeps start-up short on a 2-core
    machine and runs the pool as production does; 0 (solve in the request's thread, a
    setting production has too) is for tests of what the server answers rather than how it
    solves (the console's, the CLI's): a solver pool's forkserver and process cost a server
    start about 3 s of CPU on a slow 2-core machine (5.9 -> 2.7 CPU-s for one worker).

    The server's output goes to `log` (default: a temporary file): a pipe nobody reads fills
    up after a few thousand access-log lines and the server then blocks.
    """
    upgrade(database_url)
    engine = make_engine(database_url)
    with session_scope(write=True, engine=engine) as session:
        _, key = create_key(session, name="live-admin", scope="admin", actor=None)
    engine.dispose()
    port = _free_port()
    # (Set after os.environ: the `db` fixture sets 0 for the in-process apps of the tests.)
    env = {
        **os.environ,
        "TCPCAL_SOLVE_PROCESSES": str(solvers),
        "TCPCAL_DATABASE_URL": database_url,
    }
    tcpcal = Path(sys.executable).parent / "tcpcal"
    output = log if log is not None else tempfile.TemporaryFile()  # noqa: SIM115 (closed below)
    proc = subprocess.Popen(
        [
            str(tcpcal),
            "serve",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--workers",
            str(workers),
        ],
        cwd=REPO,
        env=env,
        stdout=output,
        stderr=subprocess.STDOUT,
        start_new_session=process_group,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        _wait_until_ready(proc, url, output)
        yield LiveServer(url, key, proc)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if log is None:
            output.close()
