"""Stopping a server with Ctrl-C leaves a clean log: the solver processes used to die with a
KeyboardInterrupt traceback each, and the resource tracker reported "10 leaked semaphore
objects" for `tcpcal serve --workers 2`."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from typing import IO

import pytest

from testbed.databases import fresh_database
from testbed.live_server import live_server

pytestmark = pytest.mark.live


def log_text(log: IO[bytes]) -> str:
    """Everything the server wrote so far, read through a handle of its own (a seek on the
    server's shared one would move where the server writes next)."""
    return Path(log.name).read_text()


def test_ctrl_c_stops_every_process_without_a_traceback_or_a_leak(tmp_path: Path) -> None:
    with (
        fresh_database("sqlite", tmp_path, None) as url,
        (tmp_path / "server.log").open("ab") as log,
        live_server(url, workers=2, log=log, process_group=True) as server,
    ):
        assert server.process is not None
        # /ready answers as soon as one worker is up: wait for both, or Ctrl-C lands in the
        # middle of the other's start-up (a traceback that is uvicorn's, not a leak).
        deadline = time.monotonic() + 60
        while log_text(log).count("Application startup complete") < 2:
            assert time.monotonic() < deadline, log_text(log)
            time.sleep(0.2)
        with server.client() as http:  # the solver pool did work before the stop
            body = {"method": "manual", "tcp": {"position_mm": [0, 0, 100]}}
            assert http.post("/v1/solve", json=body).status_code == 200
        os.killpg(server.process.pid, signal.SIGINT)  # what a terminal's Ctrl-C sends
        assert server.process.wait(timeout=30) == 0
        text = log_text(log)
    assert "Shutting down" in text
    assert "leaked" not in text
    assert "Traceback" not in text
    assert "KeyboardInterrupt" not in text
