"""In-process timing of a stored calibration and a fleet page, with the SQL each sends.

For each database (SQLite; PostgreSQL when reachable): a migrated database, 5 robots of 10
tools (as bench/wrk_load.py seeds), then N POST /v1/tools/{id}/calibrations (xyz_npoint, 8
simulated touches, activate=never: each stores a new version of the same tool), N more with
activate=auto (each version is also activated: calibrations_8_auto) and N GET
/v1/tools?limit=50, through fastapi's TestClient with TCPCAL_SOLVE_PROCESSES=0 (the solve
and the write in the request's thread). Each request is timed: the table gives the median
wall time over all of them, the median CPU time of this process (every thread: client, event
loop, worker; what other work on a shared machine disturbs least), and the median wall time
over the first and the last fifth (a cost that grows with the tool's versions shows as last >
first). The statements one request sends to the driver are counted and listed (--sql):
SQLAlchemy's cursor events and app.storage.db's driver reads and writes; BEGIN and COMMIT are not.

`--profile PREFIX` runs each scenario's requests again on a TestClient of their own with
cProfile in every thread it starts (cProfile sees its own thread only) and writes
PREFIX-<database>-<scenario>.prof and its -cumulative.txt and -tottime.txt listings.

Run from the repository root: `.venv/bin/python -m bench.write_path [--n 200] [--sql]`.
Writes bench/results/write_path.json and bench/results/write_path.md (not with --profile or
--no-save).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import platform
import pstats
import tempfile
import threading
import time
import warnings
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from statistics import median
from typing import Any

from sqlalchemy import Engine, event

import app.storage.db as appdb
from bench.wrk_load import PG_URL, _pg_reachable, touches_body
from testbed.databases import fresh_database

RESULTS = Path(__file__).resolve().parent / "results"


class Statements:
    """Every statement sent to a driver while counting, by its first words."""

    def __init__(self) -> None:
        self.on = False
        self.sql: list[str] = []
        fetch, execute = appdb._fetch, appdb._execute

        def counted_fetch(conn: Any, sql: str, params: Any) -> Any:
            self._add(sql)
            return fetch(conn, sql, params)

        def counted_execute(conn: Any, sql: str, args: Any) -> None:
            self._add(sql)
            execute(conn, sql, args)

        appdb._fetch = counted_fetch  # type: ignore[assignment]
        appdb._execute = counted_execute  # type: ignore[assignment]
        event.listen(Engine, "before_cursor_execute", self._cursor)

    def _cursor(self, _conn: Any, _cursor: Any, sql: str, *_: Any) -> None:
        self._add(sql)

    def _add(self, sql: str) -> None:
        if self.on:
            self.sql.append(" ".join(sql.split())[:160])

    def take(self) -> list[str]:
        got, self.sql = self.sql, []
        return got


def run(backend: str, n: int, tmp: Path, profile: str | None, stmts: Statements) -> dict[str, Any]:
    pg = PG_URL if backend == "postgresql" else None
    with fresh_database(backend, tmp, pg, prefix="tcpcal_wpbench") as url:
        os.environ["TCPCAL_DATABASE_URL"] = url
        os.environ["TCPCAL_SOLVE_PROCESSES"] = "0"
        os.environ.pop("TCPCAL_BOOTSTRAP_ADMIN_KEY", None)
        from app.config import get_settings
        from app.main import create_app
        from app.services.keys import create_key
        from app.storage.db import dispose_engines, session_scope
        from app.storage.migrate import upgrade

        dispose_engines()
        get_settings.cache_clear()
        upgrade(url)
        with session_scope(write=True) as session:
            _, key = create_key(session, name="bench", scope="admin", actor=None)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from fastapi.testclient import TestClient
        auth = {"Authorization": f"Bearer {key}"}
        try:
            with TestClient(create_app()) as http:
                http.headers.update(auth)
                tool_id = _seed(http)
                body = touches_body({"activate": "never"})
                post = {"Content-Type": "application/json"}

                def calibrate() -> None:
                    r = http.post(f"/v1/tools/{tool_id}/calibrations", content=body, headers=post)
                    assert r.status_code == 201, r.text

                auto = touches_body({})

                def calibrate_auto() -> None:
                    r = http.post(f"/v1/tools/{tool_id}/calibrations", content=auto, headers=post)
                    assert r.status_code == 201, r.text
                    assert r.json()["active"], r.text

                def fleet() -> None:
                    r = http.get("/v1/tools?limit=50")
                    assert r.status_code == 200, r.text
                    assert len(r.json()["items"]) == 50

                out = {}
                plan = (
                    ("calibrations_8", calibrate),
                    ("calibrations_8_auto", calibrate_auto),
                    ("fleet_50", fleet),
                )
                for name, call in plan:
                    for _ in range(5):  # warm up
                        call()
                    stmts.on = True
                    call()
                    sql = stmts.take()
                    stmts.on = False
                    times, cpu = _timed(call, n)
                    if profile:
                        _profiled(http, name, tool_id, body, n, f"{profile}-{backend}-{name}")
                    fifth = max(1, n // 5)
                    out[name] = {
                        "median_ms": median(times),
                        "median_cpu_ms": median(cpu),
                        "first_fifth_ms": median(times[:fifth]),
                        "last_fifth_ms": median(times[-fifth:]),
                        "statements": len(sql),
                        "sql": [f"{c} x {s}" for s, c in Counter(sql).items()],
                    }
        finally:
            dispose_engines()
            get_settings.cache_clear()
    return {"backend": backend, "n": n, "scenarios": out}


def _profiled(http: Any, name: str, tool_id: str, body: str, n: int, prefix: str) -> None:
    """The scenario's requests again on a new TestClient (its own event loop and worker
    threads), every one of its threads profiled."""
    from fastapi.testclient import TestClient

    from app.main import create_app

    threads = ThreadProfiles()
    with TestClient(create_app(), headers=dict(http.headers)) as other:
        for _ in range(n):
            if name.startswith("calibrations_8"):
                r = other.post(
                    f"/v1/tools/{tool_id}/calibrations",
                    content=body if name == "calibrations_8" else touches_body({}),
                    headers={"Content-Type": "application/json"},
                )
            else:
                r = other.get("/v1/tools?limit=50")
            assert r.status_code in (200, 201), r.text
    threads.dump(prefix)


def _seed(http: Any) -> str:
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
    return tool_id


def _timed(call: Callable[[], None], n: int) -> tuple[list[float], list[float]]:
    """Each call's wall time and this process's CPU time (every thread: client, event loop,
    worker), ms. The CPU time is what other work on a shared machine disturbs least."""
    times, cpu = [], []
    for _ in range(n):
        started, cpu_started = time.perf_counter(), time.process_time()
        call()
        times.append((time.perf_counter() - started) * 1e3)
        cpu.append((time.process_time() - cpu_started) * 1e3)
    return times, cpu


class ThreadProfiles:
    """cProfile in every thread started while installed (the TestClient's event loop and the
    worker threads that run the app's sync code): cProfile.Profile sees its own thread only."""

    def __init__(self) -> None:
        self.profiles: list[cProfile.Profile] = []
        self._run = threading.Thread._bootstrap_inner  # type: ignore[attr-defined]
        profiles, run = self.profiles, self._run

        def profiled(thread: threading.Thread) -> None:
            prof = cProfile.Profile()
            profiles.append(prof)
            prof.enable()
            try:
                run(thread)
            finally:
                prof.disable()

        threading.Thread._bootstrap_inner = profiled  # type: ignore[attr-defined]

    def dump(self, prefix: str) -> None:
        threading.Thread._bootstrap_inner = self._run  # type: ignore[attr-defined]
        stats = pstats.Stats(*self.profiles)
        stats.dump_stats(f"{prefix}.prof")
        for key in ("cumulative", "tottime"):
            with open(f"{prefix}-{key}.txt", "w") as f:
                pstats.Stats(f"{prefix}.prof", stream=f).sort_stats(key).print_stats(60)


def markdown(results: list[dict[str, Any]]) -> str:
    lines = [
        "| database | scenario | n | median ms | median CPU ms | first fifth ms | last fifth ms "
        "| statements |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for res in results:
        for name, r in res["scenarios"].items():
            lines.append(
                f"| {res['backend']} | {name} | {res['n']} | {r['median_ms']:.2f} "
                f"| {r['median_cpu_ms']:.2f} "
                f"| {r['first_fifth_ms']:.2f} | {r['last_fifth_ms']:.2f} | {r['statements']} |"
            )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=200, help="requests per scenario")
    parser.add_argument("--backends", default="sqlite,postgresql")
    parser.add_argument("--profile", help="cProfile each scenario to PREFIX-<backend>-<name>")
    parser.add_argument("--sql", action="store_true", help="print each request's statements")
    parser.add_argument("--no-save", action="store_true")
    args = parser.parse_args()
    stmts = Statements()
    backends = [b for b in args.backends.split(",") if b != "postgresql" or _pg_reachable()]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for backend in backends:
            results.append(run(backend, args.n, Path(tmp), args.profile, stmts))
            if args.sql:
                for name, r in results[-1]["scenarios"].items():
                    print(f"-- {backend} {name}: {r['statements']} statements")
                    print("\n".join(r["sql"]))
    md = markdown(results)
    print(md)
    if args.no_save or args.profile:
        return
    meta = {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
    }
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "write_path.json").write_text(
        json.dumps({"meta": meta, "results": results}, indent=2) + "\n"
    )
    (RESULTS / "write_path.md").write_text(md)


if __name__ == "__main__":
    main()
