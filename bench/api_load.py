"""HTTP load on a real `tcpcal serve` (SQLite) against a bare FastAPI app on the same uvicorn.

For 1 and 2 workers, both servers run side by side on loopback; scenarios are measured in
interleaved rounds (so drift on a noisy machine hits all of them alike) by CONCURRENCY
threads, each with its own keep-alive httpx client:

- bare: GET /constant of bench/bare_app.py (no auth, no database, constant JSON)
- tcp: GET /v1/tools/{id}/tcp (API key, database read, ETag)
- tcp_kuka: GET /v1/tools/{id}/tcp?format=kuka (adds the KRL text)
- tcp_304: the same with If-None-Match: <ETag> -> 304
- solve_8: POST /v1/solve, xyz_npoint, 8 touches as xyz_wxyz

Reports requests/s and p50/p95/p99 latency, and each scenario's ratio to `bare` measured in
the same run (throughput ratio ours/bare, latency ratio ours/bare).

Run from the repository root: `.venv/bin/python -m bench.api_load [--quick]`.
Writes bench/results/api_load.json and bench/results/api_load.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import numpy as np

import tests.live.server as live
from app.kinematics.poses import pose_to_format
from tests.live.server import fresh_database, live_server
from tests.sim.touches import simulate_touches

RESULTS = Path(__file__).resolve().parent / "results"
REPO = Path(__file__).resolve().parents[1]
CONCURRENCY = 8
SCENARIOS = ("bare", "tcp", "tcp_kuka", "tcp_304", "solve_8")
FULL = {"rounds": 4, "seconds_per_slice": 2.0, "max_requests_per_slice": 20_000}
QUICK = {"rounds": 2, "seconds_per_slice": 0.5, "max_requests_per_slice": 5_000}


@dataclass
class Request:
    """One scenario's request: method, URL, headers, JSON body, the status it must answer."""

    method: str
    url: str
    headers: dict[str, str]
    expected_status: int
    body: Any = None


@dataclass
class Samples:
    """Latencies (s) of the successful requests of one scenario, its errors and busy time."""

    latencies_s: list[float] = field(default_factory=list)
    errors: int = 0
    wall_s: float = 0.0


@contextmanager
def tcpcal_server(tmp: Path, workers: int, log: Any) -> Iterator[live.LiveServer]:
    """`tcpcal serve --workers N` on a fresh SQLite database, output to `log`."""
    with (
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=workers, log=log) as srv,
    ):
        yield srv


@dataclass
class BareServer:
    """bench.bare_app being served: its URL and process."""

    url: str
    proc: subprocess.Popen[bytes]

    def wait_until_ready(self, timeout_s: float = 60.0) -> None:
        """Poll GET /constant until it answers 200."""
        deadline = time.monotonic() + timeout_s
        while True:
            if self.proc.poll() is not None:
                raise RuntimeError("bare server exited early; see its log")
            try:
                if httpx.get(f"{self.url}/constant", timeout=1).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"bare server did not answer within {timeout_s} s")
            time.sleep(0.2)


@contextmanager
def bare_server(workers: int, log: Any) -> Iterator[BareServer]:
    """bench.bare_app under uvicorn.run with the arguments `tcpcal serve` uses (not yet ready)."""
    port = live._free_port()
    code = (
        "import uvicorn; from app.server import HTTP_PROTOCOL; "
        "uvicorn.run('bench.bare_app:app', host='127.0.0.1', "
        f"port={port}, workers={workers}, proxy_headers=True, http=HTTP_PROTOCOL)"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code], cwd=REPO, stdout=log, stderr=subprocess.STDOUT
    )
    try:
        yield BareServer(f"http://127.0.0.1:{port}", proc)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def solve_body() -> dict[str, Any]:
    """An xyz_npoint solve of 8 simulated touches in xyz_wxyz."""
    touches = simulate_touches(8, seed=7, touch_noise_mm=0.05)
    poses = [pose_to_format("xyz_wxyz", touches.R[i], touches.f[i]) for i in range(8)]
    return {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": poses}


def build_requests(srv: live.LiveServer, bare_url: str) -> dict[str, Request]:
    """Seed a robot and a tool with an active TCP; the request of every scenario."""
    with srv.client() as http:
        robot = http.post("/v1/robots", json={"name": "bench", "vendor": "KUKA"}).json()
        tool = http.post(
            f"/v1/robots/{robot['id']}/tools", json={"name": "torch", "slot": 3}
        ).json()
        calibration = http.post(
            f"/v1/tools/{tool['id']}/calibrations",
            json={"method": "manual", "tcp": {"position_mm": [0, 0, 150]}},
        )
        assert calibration.status_code == 201, calibration.text
        etag = http.get(f"/v1/tools/{tool['id']}/tcp").headers["etag"]
    auth = {"Authorization": f"Bearer {srv.admin_key}"}
    tcp_url = f"{srv.url}/v1/tools/{tool['id']}/tcp"
    return {
        "bare": Request("GET", f"{bare_url}/constant", {}, 200),
        "tcp": Request("GET", tcp_url, auth, 200),
        "tcp_kuka": Request("GET", f"{tcp_url}?format=kuka", auth, 200),
        "tcp_304": Request("GET", tcp_url, {**auth, "If-None-Match": etag}, 304),
        "solve_8": Request("POST", f"{srv.url}/v1/solve", auth, 200, body=solve_body()),
    }


def run_slice(
    request: Request, clients: list[httpx.Client], seconds: float, max_requests: int
) -> Samples:
    """CONCURRENCY threads send `request` back to back for `seconds` or `max_requests`."""
    samples = Samples()
    lock = threading.Lock()
    sent = [0]
    stop_at = time.perf_counter() + seconds

    def worker(client: httpx.Client) -> None:
        latencies, errors = [], 0
        while time.perf_counter() < stop_at:
            with lock:
                if sent[0] >= max_requests:
                    break
                sent[0] += 1
            t0 = time.perf_counter()
            try:
                response = client.request(
                    request.method, request.url, headers=request.headers, json=request.body
                )
                ok = response.status_code == request.expected_status
            except httpx.HTTPError:
                ok = False
            if ok:
                latencies.append(time.perf_counter() - t0)
            else:
                errors += 1
        with lock:
            samples.latencies_s.extend(latencies)
            samples.errors += errors

    threads = [threading.Thread(target=worker, args=(client,)) for client in clients]
    t0 = time.perf_counter()
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    samples.wall_s = time.perf_counter() - t0
    return samples


def measure(
    requests: dict[str, Request], rounds: int, seconds: float, max_requests: int
) -> dict[str, Samples]:
    """Every scenario, interleaved over `rounds`, after a short warm-up of each."""
    clients = [httpx.Client(timeout=30) for _ in range(CONCURRENCY)]
    try:
        for request in requests.values():
            run_slice(request, clients, min(0.25, seconds), max_requests)
        totals = {name: Samples() for name in requests}
        for _ in range(rounds):
            for name, request in requests.items():
                part = run_slice(request, clients, seconds, max_requests)
                totals[name].latencies_s.extend(part.latencies_s)
                totals[name].errors += part.errors
                totals[name].wall_s += part.wall_s
        return totals
    finally:
        for client in clients:
            client.close()


def summarize(samples: Samples) -> dict[str, float | int]:
    """Requests/s and latency percentiles (ms) of one scenario."""
    latencies_ms = 1e3 * np.asarray(samples.latencies_s)
    p50, p95, p99 = np.percentile(latencies_ms, [50, 95, 99])
    return {
        "requests": len(samples.latencies_s),
        "errors": samples.errors,
        "requests_per_s": len(samples.latencies_s) / samples.wall_s,
        "p50_ms": float(p50),
        "p95_ms": float(p95),
        "p99_ms": float(p99),
    }


def with_ratios(rows: dict[str, dict[str, float | int]]) -> None:
    """Add each scenario's throughput and latency ratios to `bare`, in place."""
    bare = rows["bare"]
    for row in rows.values():
        row["rps_vs_bare"] = float(row["requests_per_s"]) / float(bare["requests_per_s"])
        for p in ("p50", "p95", "p99"):
            row[f"{p}_vs_bare"] = float(row[f"{p}_ms"]) / float(bare[f"{p}_ms"])


def bench_workers(workers: int, config: dict[str, Any], log: Any) -> dict[str, Any]:
    """Start both servers with `workers` workers, measure every scenario, stop them."""
    with (
        tempfile.TemporaryDirectory() as tmp,
        bare_server(workers, log) as bare,
        tcpcal_server(Path(tmp), workers, log) as srv,
    ):
        bare.wait_until_ready()
        requests = build_requests(srv, bare.url)
        samples = measure(
            requests,
            config["rounds"],
            config["seconds_per_slice"],
            config["max_requests_per_slice"],
        )
    rows = {name: summarize(samples[name]) for name in SCENARIOS}
    with_ratios(rows)
    return rows


COLUMNS: list[tuple[str, str, Callable[[Any], str]]] = [
    ("requests", "requests", lambda v: f"{v}"),
    ("errors", "errors", lambda v: f"{v}"),
    ("requests_per_s", "req/s", lambda v: f"{v:.0f}"),
    ("p50_ms", "p50 ms", lambda v: f"{v:.2f}"),
    ("p95_ms", "p95 ms", lambda v: f"{v:.2f}"),
    ("p99_ms", "p99 ms", lambda v: f"{v:.2f}"),
    ("rps_vs_bare", "req/s vs bare", lambda v: f"{v:.2f}"),
    ("p50_vs_bare", "p50 vs bare", lambda v: f"{v:.2f}"),
    ("p99_vs_bare", "p99 vs bare", lambda v: f"{v:.2f}"),
]


def markdown_table(results: dict[str, dict[str, dict[str, Any]]]) -> str:
    """One row per (workers, scenario)."""
    head = ["workers", "scenario", *(title for _, title, _ in COLUMNS)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for workers, rows in results.items():
        for name, row in rows.items():
            cells = [workers, name, *(fmt(row[key]) for key, _, fmt in COLUMNS)]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def git_commit() -> str:
    """The checked-out commit, or "unknown"."""
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True
        )
        return out.stdout.strip() or "unknown"
    except OSError:
        return "unknown"


def main() -> None:
    """Run the benchmark, print the table, write the results files."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="about 20 s instead of about 90 s")
    args = parser.parse_args()
    config = QUICK if args.quick else FULL
    started = time.perf_counter()
    RESULTS.mkdir(exist_ok=True)
    results: dict[str, dict[str, dict[str, Any]]] = {}
    log_path = Path(tempfile.mkstemp(prefix="api_load_servers_", suffix=".log")[1])
    try:
        with log_path.open("wb") as log:
            for workers in (1, 2):
                results[str(workers)] = bench_workers(workers, config, log)
    except Exception:
        print(f"server output: {log_path}", file=sys.stderr)
        raise
    log_path.unlink()
    elapsed = time.perf_counter() - started
    meta = {
        "quick": args.quick,
        "concurrency": CONCURRENCY,
        **config,
        "database": "sqlite",
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "commit": git_commit(),
        "elapsed_s": round(elapsed, 1),
        "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    table = markdown_table(results)
    print(table)
    print(f"\n{elapsed:.0f} s; ratios are ours / bare from this run")
    (RESULTS / "api_load.json").write_text(
        json.dumps({"meta": meta, "results": results}, indent=2) + "\n"
    )
    (RESULTS / "api_load.md").write_text(
        "# API load: tcpcal vs a bare FastAPI endpoint\n\n"
        f"`python -m bench.api_load{' --quick' if args.quick else ''}` on {meta['date']} "
        f"(commit {meta['commit']}, {meta['cpus']} CPUs, Python {meta['python']}): "
        f"{CONCURRENCY} concurrent keep-alive httpx clients on loopback (load generator on the "
        f"same machine), {config['rounds']} interleaved rounds of {config['seconds_per_slice']} s "
        "per scenario, SQLite. Ratios are ours / bare measured in this same run: `req/s vs "
        "bare` below 1 is slower, `p50 vs bare` above 1 is slower.\n\n"
        "- bare: GET /constant, bench/bare_app.py (no auth, no database)\n"
        "- tcp: GET /v1/tools/{id}/tcp (API key, database read, ETag)\n"
        "- tcp_kuka: GET /v1/tools/{id}/tcp?format=kuka\n"
        "- tcp_304: the same with If-None-Match -> 304\n"
        "- solve_8: POST /v1/solve, xyz_npoint, 8 touches in xyz_wxyz\n\n" + table + "\n"
    )


if __name__ == "__main__":
    main()
