"""Screenshots of the console for the README, from a fresh demo database.

    .venv/bin/python scripts/screenshots.py   # writes docs/screenshots/*.png

fleet, tool and report at 1360 px; the calibrate page (a guided session on the demo's torch,
five touches typed with 0.04 mm of noise, the robot given a controller connection so Capture
is offered) at 1400 px and at a 768 px tablet.

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
import numpy as np
from playwright.sync_api import Browser, Page, sync_playwright
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_from_format, pose_to_format

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


def _key(env: dict[str, str], scope: str) -> str:
    made = subprocess.run(
        [TCPCAL, "keys", "create", "--scope", scope, "--name", f"screenshots-{scope}"],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return next(line.split()[1] for line in made.splitlines() if line.startswith("key:"))


#: Where the session's touches meet, and the touch noise (mm).
POINT = np.array([900.0, -150.0, 300.0])
NOISE_MM = 0.04


def _guided_session(url: str, key: str, torch: dict[str, object]) -> None:
    """A session half way: five typed touches following the suggestions, a target it has not
    reached, so the page shows the estimate, residuals and the next touch."""
    http = httpx.Client(base_url=url, headers={"Authorization": f"Bearer {key}"})
    robot_id, tool_id = torch["robot_id"], torch["id"]
    with socket.socket() as sock:  # a port nothing answers on: the page only offers Capture
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    body = {"protocol": "kuka_kvp", "host": "127.0.0.1", "port": port}
    http.put(f"/v1/robots/{robot_id}/controller", json=body).raise_for_status()
    tcp = np.asarray(http.get(f"/v1/tools/{tool_id}/tcp").json()["tcp"]["position_mm"])
    body = {"method": "xyz_npoint", "format": "kuka_abc", "target_sigma_mm": 0.02}
    session = http.post(f"/v1/tools/{tool_id}/sessions", json=body).json()
    rng = np.random.default_rng(39)
    rotation = Rotation.from_euler("ZYX", [20.0, 5.0, 180.0], degrees=True).as_matrix()
    for _ in range(5):
        flange = POINT - rotation @ tcp + rng.normal(0.0, NOISE_MM, 3)
        pose = pose_to_format("kuka_abc", rotation, flange)
        session = http.post(f"/v1/sessions/{session['id']}/poses", json={"pose": pose}).json()
        rotation = np.asarray(pose_from_format("kuka_abc", session["next_pose"])[0])


def _shoot_calibrate(browser: Browser, url: str, key: str, tool_id: str) -> None:
    for width, height in ((1400, 900), (768, 1024)):
        page = browser.new_page(viewport={"width": width, "height": height})
        page.goto(f"{url}/ui/tools/{tool_id}/calibrate")
        page.fill("input[name=api_key]", key)
        page.click("#sign-in button[type=submit]")
        page.wait_for_selector("#next-words")
        page.keyboard.press("Tab")  # the focus ring on the first field, as at the cell
        page.screenshot(path=OUT / f"calibrate-{width}.png", full_page=True)
        print(f"wrote {OUT / f'calibrate-{width}'}.png")
        page.close()


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "TCPCAL_DATABASE_URL": f"sqlite:///{tmp}/demo.sqlite3"}
        subprocess.run([TCPCAL, "demo"], env=env, check=True)
        key = _key(env, "read")
        admin = _key(env, "admin")
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
                _guided_session(url, admin, torch)
                _shoot_calibrate(browser, url, admin, torch["id"])
                browser.close()
        finally:
            server.terminate()
            server.wait(timeout=15)


if __name__ == "__main__":
    main()
