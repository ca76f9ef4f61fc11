"""`tcpcal calibrate --guided` at a terminal: the real command in a pseudo-terminal 80 columns
wide against a live server, its answers typed as a person types them (echoed, Enter ends
the line). The line `q` prints must continue the session when pasted into the shell: rich
wrapped it at the terminal's width, so a pasted line was `tcpcal calibrate ID --guided`
alone, and without --format it said "error: give --format" (issue 51, defects 2 and 3)."""

from __future__ import annotations

import fcntl
import os
import re
import select
import shlex
import struct
import subprocess
import sys
import termios
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from testbed.live_server import LiveServer, fresh_database, live_server

pytestmark = pytest.mark.live

TCPCAL = Path(sys.executable).parent / "tcpcal"
#: Colours, cursor moves and the like, which a terminal shows and does not copy.
ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|\x1b\][^\x07]*\x07")


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    tmp = tmp_path_factory.mktemp("terminal")
    with fresh_database("sqlite", tmp, None) as url, live_server(url, workers=1, solvers=0) as srv:
        yield srv


class Terminal:
    """One command in a pseudo-terminal of 80 columns: what it wrote, as a terminal shows it,
    and lines typed when it asks."""

    def __init__(self, args: list[str], server: LiveServer) -> None:
        self.master, slave = os.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
        env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
        env.update(TCPCAL_URL=server.url, TCPCAL_API_KEY=server.admin_key, TERM="xterm")
        self.proc = subprocess.Popen(
            args, stdin=slave, stdout=slave, stderr=slave, env=env, start_new_session=True
        )
        os.close(slave)
        self.shown = ""

    def _read(self, timeout_s: float) -> bool:
        """Whatever the command wrote within `timeout_s`; False once it has ended."""
        ready, _, _ = select.select([self.master], [], [], timeout_s)
        if not ready:
            return self.proc.poll() is None
        try:
            chunk = os.read(self.master, 4096)
        except OSError:  # the command ended and closed the terminal
            return False
        self.shown += ANSI.sub("", chunk.decode(errors="replace")).replace("\r", "")
        return bool(chunk)

    def wait_for(self, text: str, timeout_s: float = 60.0, *, after: int = 0) -> None:
        """Read until `text` is shown (or the command ends), past the first `after` characters
        shown (len(shown) before a line is typed: a prompt shown again)."""
        deadline = time.monotonic() + timeout_s
        while text not in self.shown[after:] and time.monotonic() < deadline and self._read(0.2):
            pass
        assert text in self.shown[after:], self.shown

    def type(self, line: str) -> None:
        os.write(self.master, line.encode() + b"\r")  # Enter, as a keyboard sends it

    def end(self, timeout_s: float = 60.0) -> int:
        """Read all the command writes until it ends; its exit code."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and self._read(0.2):
            pass
        code = self.proc.wait(max(deadline - time.monotonic(), 1.0))
        os.close(self.master)
        return code


def test_the_line_q_prints_continues_the_session_when_pasted_at_an_80_column_terminal(
    server: LiveServer,
) -> None:
    with server.client() as http:
        robot = http.post("/v1/robots", json={"name": "tm5", "vendor": "Techman"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "gripper"}).json()
    started = Terminal(
        [str(TCPCAL), "calibrate", tool["id"], "--guided", "--format", "techman_rxyz"], server
    )
    started.wait_for("touch 1> ")
    started.type("q")
    assert started.end() == 0, started.shown
    found = re.findall(r"^left open: (tcpcal .*)$", started.shown, re.MULTILINE)
    assert len(found) == 1, repr(started.shown)
    [line] = found
    words = shlex.split(line)
    assert words[:2] == ["tcpcal", "calibrate"], line
    assert "--session" in words, f"the line broke at the terminal's width: {started.shown!r}"

    pasted = Terminal([str(TCPCAL), *words[1:]], server)
    pasted.wait_for("touch 1> ")
    assert "type each touch's pose (techman_rxyz)" in " ".join(pasted.shown.split())
    pasted.type("887.5 18.251 568.212 0 0 -155")
    pasted.wait_for("touch 2> ")
    pasted.type("q")
    assert pasted.end() == 0, pasted.shown
    sid = words[words.index("--session") + 1]
    with server.client() as http:
        kept = http.get(f"/v1/sessions/{sid}").json()
    assert (kept["format"], kept["poses"]) == (
        "techman_rxyz",
        [[887.5, 18.251, 568.212, 0.0, 0.0, -155.0]],
    )
