"""HTTP load from wrk on a real `tcpcal serve` against a bare FastAPI app on the same uvicorn.

For each database (SQLite; PostgreSQL when reachable) and 1 and 2 workers, our server and
bench/bare_app.py run side by side on loopback with the same uvicorn arguments. Every
scenario is measured by wrk (-t1 -c16, `--latency`), in interleaved rounds so that drift on
a noisy machine hits all of them alike; the table gives medians over the rounds and each
scenario's ratio to `bare` in the same run:

- bare: GET /constant (no auth, no database, constant JSON)
- tcp, tcp_304, tcp_kuka: GET /v1/tools/{id}/tcp (plain; If-None-Match -> 304; ?format=kuka)
- fleet_50: GET /v1/tools?limit=50 (50 tools of 5 robots)
- solve_8: POST /v1/solve, xyz_npoint, 8 touches
- calibrations_8: POST /v1/tools/{id}/calibrations, 8 touches (each stores a version)

A response that is not the expected status counts as an error and is reported.
wrk comes from Debian's package (`apt-get install wrk`); the bench says so when it is missing.

Run from the repository root: `.venv/bin/python -m bench.wrk_load [--quick]`.
Writes bench/results/wrk_load.json and bench/results/wrk_load.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from statistics import median
from typing import Any

import httpx

import testbed.live_server as live
from app.kinematics.poses import pose_to_format
from app.services import solve_pool
from testbed.live_server import fresh_database, live_server
from testbed.sim.touches import simulate_touches

RESULTS = Path(__file__).resolve().parent / "results"
REPO = Path(__file__).resolve().parents[1]
SCENARIOS = ("bare", "tcp", "tcp_304", "tcp_kuka", "fleet_50", "solve_8", "calibrations_8")
FULL = {"rounds": 3, "seconds": 4}
QUICK = {"rounds": 1, "seconds": 2}
PG_URL = os.environ.get(
    "TCPCAL_TEST_DATABASE_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test"
)


@dataclass
class Scenario:
    method: str
    url: str
    headers: dict[str, str]
    expected: int
    body: str | None = None


@dataclass
class Run:
    requests_per_s: float
    p50_ms: float
    p99_ms: float
    errors: int


def _wrk() -> str:
    path = shutil.which("wrk")
    if path is None:
        sys.exit("wrk is not installed: apt-get install wrk (Debian's package)")
    return path


LUA = """
wrk.method = {method}
wrk.body = {body}
{headers}
local expected = {expected}
local bad = 0
response = function(status, headers, body)
  if status ~= expected then bad = bad + 1 end
end
done = function(summary, latency, requests)
  io.write(string.format("BAD %d\\n", bad))
end
"""


def run_wrk(s: Scenario, seconds: float, tmp: Path) -> Run:
    """One wrk run: requests/s, p50 and p99 latency, responses other than expected."""
    headers = "\n".join(
        f"wrk.headers[{json.dumps(k)}] = {json.dumps(v)}" for k, v in s.headers.items()
    )
    script = tmp / "scenario.lua"
    script.write_text(
        LUA.format(
            method=json.dumps(s.method),
            body=json.dumps(s.body) if s.body is not None else "nil",
            headers=headers,
            expected=s.expected,
        )
    )
    out = subprocess.run(
        [_wrk(), "-t1", "-c16", f"-d{seconds}s", "--latency", "-s", str(script), s.url],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    rps = float(re.search(r"Requests/sec:\s+([\d.]+)", out).group(1))  # type: ignore[union-attr]
    bad = int(re.search(r"BAD (\d+)", out).group(1))  # type: ignore[union-attr]
    errors = re.search(r"Socket errors: connect (\d+), read (\d+), write (\d+), timeout (\d+)", out)
    if errors:
        bad += sum(int(g) for g in errors.groups())
    return Run(rps, _percentile(out, "50%"), _percentile(out, "99%"), bad)


def _percentile(out: str, label: str) -> float:
    match = re.search(rf"^\s+{re.escape(label)}\s+([\d.]+)(us|ms|s)\s*$", out, re.M)
    assert match, out
    value, unit = float(match.group(1)), match.group(2)
    return value * {"us": 1e-3, "ms": 1.0, "s": 1e3}[unit]


@contextmanager
def bare_server(workers: int, log: Any) -> Iterator[str]:
    """bench.bare_app under uvicorn.run with the arguments `tcpcal serve` uses."""
    port = live._free_port()
    code = (
        "import uvicorn; from app.server import HTTP_PROTOCOL; "
        "uvicorn.run('bench.bare_app:app', host='127.0.0.1', "
        f"port={port}, workers={workers}, proxy_headers=True, http=HTTP_PROTOCOL, "
        "log_level='warning', access_log=False)"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code], cwd=REPO, stdout=log, stderr=subprocess.STDOUT
    )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                if httpx.get(f"{url}/constant", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline or proc.poll() is not None:
                raise RuntimeError("the bare server did not start")
            time.sleep(0.2)
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=15)


def touches_body(method_fields: dict[str, Any]) -> str:
    touches = simulate_touches(8, seed=7, touch_noise_mm=0.05, tcp_mm=None)
    poses = [pose_to_format("xyz_wxyz", touches.R[i], touches.f[i]) for i in range(8)]
    return json.dumps(
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": poses, **method_fields}
    )


def scenarios(srv: live.LiveServer, bare_url: str) -> dict[str, Scenario]:
    """Seed 5 robots with 10 tools each (one with an active TCP); every scenario's request."""
    with srv.client() as http:
        tool_id = ""
        for r in range(5):
            robot = http.post("/v1/robots", json={"name": f"r{r}", "cell": f"c{r % 2}"}).json()
            for t in range(10):
                tool = http.post(
                    f"/v1/robots/{robot['id']}/tools", json={"name": f"t{t}", "slot": t + 1}
                ).json()
                tool_id = tool_id or tool["id"]
        first = http.post(
            f"/v1/tools/{tool_id}/calibrations",
            content=touches_body({}),
            headers={"Content-Type": "application/json"},
        )
        assert first.status_code == 201, first.text
        etag = http.get(f"/v1/tools/{tool_id}/tcp").headers["etag"]
    auth = {"Authorization": f"Bearer {srv.admin_key}"}
    post = {**auth, "Content-Type": "application/json"}
    tcp = f"{srv.url}/v1/tools/{tool_id}/tcp"
    return {
        "bare": Scenario("GET", f"{bare_url}/constant", {}, 200),
        "tcp": Scenario("GET", tcp, auth, 200),
        "tcp_304": Scenario("GET", tcp, {**auth, "If-None-Match": etag}, 304),
        "tcp_kuka": Scenario("GET", f"{tcp}?format=kuka", auth, 200),
        "fleet_50": Scenario("GET", f"{srv.url}/v1/tools?limit=50", auth, 200),
        "solve_8": Scenario("POST", f"{srv.url}/v1/solve", post, 200, touches_body({})),
        "calibrations_8": Scenario(
            "POST",
            f"{srv.url}/v1/tools/{tool_id}/calibrations",
            post,
            201,
            touches_body({"activate": "never"}),
        ),
    }


def measure(
    backend: str, workers: int, settings: dict[str, float], tmp: Path, names: tuple[str, ...]
) -> dict[str, Any]:
    logs = Path(tempfile.gettempdir()) / "tcpcal-wrk-logs"
    logs.mkdir(exist_ok=True)
    log = (logs / f"{backend}-{workers}.log").open("wb")  # kept for a look after the run
    pg = PG_URL if backend == "postgresql" else None
    with (
        fresh_database(backend, tmp, pg, prefix="tcpcal_bench") as url,
        live_server(url, workers=workers, log=log) as srv,
        bare_server(workers, log) as bare_url,
    ):
        plan = scenarios(srv, bare_url)
        runs: dict[str, list[Run]] = {name: [] for name in names}
        for name in names:  # warm up: connection pools, solver processes, caches
            run_wrk(plan[name], 1, tmp)
        for _ in range(int(settings["rounds"])):
            for name in names:
                runs[name].append(run_wrk(plan[name], settings["seconds"], tmp))
    bare_rps = median(r.requests_per_s for r in runs["bare"])
    bare_p99 = median(r.p99_ms for r in runs["bare"])
    rows = {}
    for name, got in runs.items():
        rps = median(r.requests_per_s for r in got)
        p99 = median(r.p99_ms for r in got)
        rows[name] = {
            "requests_per_s": rps,
            "p50_ms": median(r.p50_ms for r in got),
            "p99_ms": p99,
            "throughput_vs_bare": rps / bare_rps,
            "p99_vs_bare": p99 / bare_p99,
            "errors": sum(r.errors for r in got),
        }
    return {"backend": backend, "workers": workers, "scenarios": rows}


def markdown(results: list[dict[str, Any]]) -> str:
    """The results as a table; "x bare" to three places (0.147 is not 0.15)."""
    lines = [
        "| database | workers | scenario | req/s | x bare | p50 ms | p99 ms | p99 / bare "
        "| errors |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for res in results:
        for name, r in res["scenarios"].items():
            lines.append(
                f"| {res['backend']} | {res['workers']} | {name} | {r['requests_per_s']:.0f} "
                f"| {r['throughput_vs_bare']:.3f} | {r['p50_ms']:.1f} | {r['p99_ms']:.1f} "
                f"| {r['p99_vs_bare']:.2f} | {r['errors']} |"
            )
    return "\n".join(lines) + "\n"


def _pg_reachable() -> bool:
    try:
        socket.create_connection(("127.0.0.1", 5432), timeout=2).close()
    except OSError:
        return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="1 round of 2 s per scenario")
    parser.add_argument("--backends", default="sqlite,postgresql")
    parser.add_argument("--workers", default="1,2")
    parser.add_argument("--scenarios", default=",".join(SCENARIOS), help="bare is always run")
    parser.add_argument("--rounds", type=int, help="override the rounds")
    parser.add_argument("--no-save", action="store_true", help="print only (profiling runs)")
    args = parser.parse_args()
    # The server as deployed: its default number of solver processes (the live-test helper
    # would start one); an explicit TCPCAL_SOLVE_PROCESSES is passed through.
    os.environ.setdefault("TCPCAL_SOLVE_PROCESSES", str(solve_pool.default_processes()))
    settings: dict[str, float] = dict(QUICK if args.quick else FULL)
    if args.rounds:
        settings["rounds"] = args.rounds
    names = ("bare", *[n for n in args.scenarios.split(",") if n in SCENARIOS and n != "bare"])
    _wrk()
    backends = [b for b in args.backends.split(",") if b != "postgresql" or _pg_reachable()]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for backend in backends:
            for workers in (int(w) for w in args.workers.split(",")):
                results.append(measure(backend, workers, settings, Path(tmp), names))
                print(markdown(results[-1:]), flush=True)
    md = markdown(results)
    print(md)
    meta = {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "wrk": "-t1 -c16 --latency",
        **settings,
    }
    if args.no_save:
        return
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "wrk_load.json").write_text(
        json.dumps({"meta": meta, "results": results}, indent=2) + "\n"
    )
    (RESULTS / "wrk_load.md").write_text(md)


if __name__ == "__main__":
    main()
