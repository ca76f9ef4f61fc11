"""Screenshots of the console for the README, from a fresh demo database.

    .venv/bin/python scripts/screenshots.py   # writes docs/screenshots/{fleet,tool,report}.png

Runs `tcpcal demo` into a temporary SQLite file, creates a key, serves it on a free loopback
port and drives Debian's Chromium (TCPCAL_CHROMIUM overrides the path) through the pages.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
from playwright.sync_api import Page, sync_playwright

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "docs" / "screenshots"
TCPCAL = str(Path(sys.executable).parent / "tcpcal")
CHROMIUM = os.environ.get("TCPCAL_CHROMIUM", "/usr/bin/chromium")


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _shoot(page: Page, url: str, ready: str, name: str) -> None:
    page.goto(url)
    page.wait_for_selector(ready)
    page.wait_for_timeout(1500)  # let Plotly finish its transitions
    page.screenshot(path=OUT / f"{name}.png", full_page=True)
    print(f"wrote {OUT / name}.png")


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "TCPCAL_DATABASE_URL": f"sqlite:///{tmp}/demo.sqlite3"}
        subprocess.run([TCPCAL, "demo"], env=env, check=True)
        made = subprocess.run(
            [TCPCAL, "keys", "create", "--scope", "read", "--name", "screenshots"],
            env=env,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        key = next(line.split()[1] for line in made.splitlines() if line.startswith("key:"))
        port = _free_port()
        url = f"http://127.0.0.1:{port}"
        server = subprocess.Popen(
            [TCPCAL, "serve", "--host", "127.0.0.1", "--port", str(port)],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            for _ in range(100):
                try:
                    if httpx.get(f"{url}/ready").status_code == 200:
                        break
                except httpx.HTTPError:
                    time.sleep(0.2)
            headers = {"Authorization": f"Bearer {key}"}
            tools = httpx.get(f"{url}/v1/tools", headers=headers).json()["items"]
            torch = next(
                t for t in tools if t["robot_name"] == "weld12-kr16" and t["name"] == "torch"
            )
            with sync_playwright() as pw:
                browser = pw.chromium.launch(
                    executable_path=CHROMIUM,
                    args=["--enable-unsafe-swiftshader", "--use-angle=swiftshader"],
                )
                page = browser.new_page(viewport={"width": 1360, "height": 900})
                page.goto(f"{url}/ui/")
                page.fill("input[name=api_key]", key)
                page.click("#sign-in button[type=submit]")
                _shoot(page, f"{url}/ui/", "#fleet tbody tr", "fleet")
                _shoot(page, f"{url}/ui/tools/{torch['id']}", "#plot-tcp .main-svg", "tool")
                report = f"{url}/ui/calibrations/{torch['last_calibration']['id']}"
                _shoot(page, report, "#plot-3d canvas", "report")
                browser.close()
        finally:
            server.terminate()
            server.wait(timeout=15)


if __name__ == "__main__":
    main()
