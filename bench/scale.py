"""A million versions: the hot reads on a large database against the same reads on a small one.

For each database (SQLite; PostgreSQL when reachable) two databases are migrated and seeded
by bulk insert (not through the API): a large one (10 000 tools of 1 000 robots) and a small
one (100 tools). In both, every tool has 100 versions, each from a stored calibration, 100
activations, 10 checks and the audit rows these writes leave (tool.create,
calibration.create, version.create, tool.check): the large one holds 1 M versions, 1 M
calibrations, 1 M activations and 2.1 M audit rows. The stored JSON is copied from a real
calibration made through the API, so rows have their real size.

Measured, small against large, interleaved in rounds (medians):
- `tcpcal serve` (one worker) on each database at once, wrk -t1 -c1 (one request at a
  time: the latency a client sees) on GET /v1/tools/{id}/tcp, GET /v1/tools/{id}/versions
  (100 versions) and GET /v1/tools?limit=50 (the first and a deep page of the fleet);
- the same reads in this process through the service functions, timing only the
  database work and the Python that builds the answer;
- EXPLAIN (SQLite: EXPLAIN QUERY PLAN; PostgreSQL: EXPLAIN ANALYZE) of every statement each
  read sends to the large database, captured as it is sent. A full scan of a large table is
  flagged.

SQLite is measured as a deployment has it (no ANALYZE: the migrations do not run one);
PostgreSQL after VACUUM ANALYZE, which autovacuum does on its own after a bulk load.

Run from the repository root: `.venv/bin/python -m bench.scale [--tools N] [--backends ...]`.
Writes bench/results/scale.json and bench/results/scale.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import subprocess
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from statistics import median
from typing import Any

from sqlalchemy import Engine, event, insert, select, text

from app.security.auth import hash_key
from app.services.audit.writes import row as audit_row
from app.services.fleet import fleet
from app.services.subjects import SERVED
from app.services.tools import hot_read, versions
from app.storage.db import make_engine, session_scope
from app.storage.models import Activation, AuditEvent, Calibration, Robot, TcpVersion, Tool
from bench.wrk_load import PG_URL, _percentile, _pg_reachable, _wrk, touches_body
from testbed.live_server import LiveServer, fresh_database, live_server

RESULTS = Path(__file__).resolve().parent / "results"
VERSIONS_PER_TOOL = 100
CHECKS_PER_TOOL = 10
TOOLS_PER_ROBOT = 10
SMALL_TOOLS = 100  # two pages of 50: the small fleet page is as full as the large one
BATCH = 5_000
READS = ("tcp", "versions_100", "fleet_first_50", "fleet_deep_50")


@dataclass
class Seeded:
    """A seeded database served by a live server: what the reads need."""

    url: str
    server: LiveServer
    engine: Engine
    tool_id: str
    deep_cursor: str
    rows: dict[str, int]
    seconds: float


# ---- seeding -------------------------------------------------------------------------------


def _templates(srv: LiveServer) -> dict[str, Any]:
    """One real calibration, version and check made through the API: the rows to copy."""
    with srv.client() as http:
        robot = http.post("/v1/robots", json={"name": "template", "cell": "t"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "template"}).json()
        made = http.post(
            f"/v1/tools/{tool['id']}/calibrations",
            content=touches_body({}),
            headers={"Content-Type": "application/json"},
        )
        assert made.status_code == 201, made.text
        return {"robot": robot["id"], "tool": tool["id"], "calibration": made.json()["id"]}


def _copy_rows(engine: Engine, made: dict[str, Any]) -> dict[str, Any]:
    with engine.connect() as conn:
        cal = conn.execute(
            select(Calibration.request, Calibration.result).where(
                Calibration.id == made["calibration"]
            )
        ).one()
        ver = conn.execute(
            select(TcpVersion.position_mm, TcpVersion.quaternion).where(
                TcpVersion.tool_id == made["tool"]
            )
        ).one()
        audit = dict(
            conn.execute(
                select(AuditEvent.action, AuditEvent.details).where(
                    AuditEvent.tool_id == made["tool"]
                )
            ).all()
        )
    check = {
        "version": 1,
        "reference_point_id": None,
        "deviation_mm": [0.01, -0.02, 0.03],
        "deviation_flange_mm": [0.01, -0.02, 0.03],
        "distance_mm": 0.0374,
        "check_mm": [1.0, 2.0, 3.0],
        "within_tolerance": True,
        "summary": "within tolerance: the tool tip is 0.04 mm from where version 1 puts it",
    }
    return {
        "request": cal.request,
        "result": cal.result,
        "position": ver.position_mm,
        "quaternion": ver.quaternion,
        "calibration_audit": audit.get("calibration.create"),
        "version_audit": audit.get("version.create"),
        "check_audit": check,
    }


def _insert(conn: Any, table: Any, rows: list[dict[str, Any]]) -> None:
    for start in range(0, len(rows), BATCH):
        conn.execute(insert(table), rows[start : start + BATCH])


def seed(engine: Engine, n_tools: int, t: dict[str, Any]) -> dict[str, int]:
    """Bulk-insert n_tools tools with their full history; robot by robot, in one transaction
    per 100 tools. Returns the row counts written."""
    counts = dict.fromkeys(("robots", "tools", "calibrations", "versions", "activations"), 0)
    counts["audit_events"] = 0
    start = datetime(2024, 1, 1, tzinfo=UTC)
    per_tx = 100
    for first in range(0, n_tools, per_tx):
        robots, tools, cals, vers, acts, audit = [], [], [], [], [], []
        for i in range(first, min(first + per_tx, n_tools)):
            if i % TOOLS_PER_ROBOT == 0:
                robot_id = str(uuid.uuid4())
                robots.append(
                    {
                        "id": robot_id,
                        "name": f"robot-{i // TOOLS_PER_ROBOT:05d}",
                        "vendor": "KUKA",
                        "model": "KR 16",
                        "cell": f"cell-{i // (TOOLS_PER_ROBOT * 10):04d}",
                        "created_at": start + timedelta(seconds=i),
                        "updated_at": start + timedelta(seconds=i),
                    }
                )
            tool_id = str(uuid.uuid4())
            born = start + timedelta(seconds=i, microseconds=1)
            tools.append(
                {
                    "id": tool_id,
                    "robot_id": robot_id,
                    "name": f"tool-{i:05d}",
                    "slot": i % TOOLS_PER_ROBOT + 1,
                    "tolerance": {"rms_mm": 0.5},
                    "active_version": VERSIONS_PER_TOOL,
                    "last_version": VERSIONS_PER_TOOL,
                    "revision": 2 * VERSIONS_PER_TOOL + 1,
                    "created_at": born,
                    "updated_at": born,
                }
            )
            audit.append(_audit("tool.create", "tool", tool_id, robot_id, tool_id, born, None))
            for v in range(1, VERSIONS_PER_TOOL + 1):
                at = born + timedelta(days=v)
                cal_id = str(uuid.uuid4())
                cals.append(
                    {
                        "id": cal_id,
                        "tool_id": tool_id,
                        "method": "xyz_npoint",
                        "algorithm": "linear",
                        "status": "accepted",
                        "request": t["request"],
                        "result": t["result"],
                        "version": v,
                        "created_at": at,
                        "created_by": "bench",
                    }
                )
                vers.append(
                    {
                        "id": str(uuid.uuid4()),
                        "tool_id": tool_id,
                        "version": v,
                        "position_mm": t["position"],
                        "quaternion": t["quaternion"],
                        "source": "calibration",
                        "status": "accepted",
                        "calibration_id": cal_id,
                        "created_at": at,
                        "created_by": "bench",
                    }
                )
                acts.append(
                    {
                        "tool_id": tool_id,
                        "version": v,
                        "previous_version": v - 1 or None,
                        "reason": "calibration",
                        "activated_at": at,
                        "activated_by": "bench",
                    }
                )
                audit.append(
                    _audit(
                        "calibration.create",
                        "calibration",
                        cal_id,
                        robot_id,
                        tool_id,
                        at,
                        t["calibration_audit"],
                    )
                )
                audit.append(
                    _audit(
                        "version.create", "tool", tool_id, robot_id, tool_id, at, t["version_audit"]
                    )
                )
            for c in range(CHECKS_PER_TOOL):
                at = born + timedelta(days=10 * c + 5)
                audit.append(
                    _audit("tool.check", "tool", tool_id, robot_id, tool_id, at, t["check_audit"])
                )
        with engine.begin() as conn:
            _insert(conn, Robot.__table__, robots)
            _insert(conn, Tool.__table__, tools)
            _insert(conn, Calibration.__table__, cals)
            _insert(conn, TcpVersion.__table__, vers)
            _insert(conn, Activation.__table__, acts)
            _insert(conn, AuditEvent.__table__, audit)
        for name, rows in (
            ("robots", robots),
            ("tools", tools),
            ("calibrations", cals),
            ("versions", vers),
            ("activations", acts),
            ("audit_events", audit),
        ):
            counts[name] += len(rows)
    return counts


def _audit(
    action: str,
    resource_type: str,
    resource_id: str,
    robot_id: str,
    tool_id: str,
    at: datetime,
    details: Any,
) -> dict[str, object]:
    return audit_row(
        at=at,
        actor="bench",
        api_key_id=None,
        action=action,
        resource_type=resource_type,
        resource_id=resource_id,
        robot_id=robot_id,
        tool_id=tool_id,
        details=details,
    )


@contextmanager
def seeded(backend: str, n_tools: int, tmp: Path, log: Any) -> Iterator[Seeded]:
    with ExitStack() as stack:
        pg = PG_URL if backend == "postgresql" else None
        url = stack.enter_context(fresh_database(backend, tmp, pg, prefix="tcpcal_scale"))
        srv = stack.enter_context(live_server(url, workers=1, log=log))
        engine = make_engine(url)
        stack.callback(engine.dispose)
        made = _templates(srv)
        began = time.perf_counter()
        rows = seed(engine, n_tools, _copy_rows(engine, made))
        with engine.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
            if backend == "postgresql":
                conn.execute(text("VACUUM ANALYZE"))
        seconds = time.perf_counter() - began
        with engine.connect() as conn:
            # The target: the newest seeded tool with 100 versions; the deep page starts
            # half-way through the fleet.
            tool_id = conn.execute(
                select(Tool.id).where(Tool.name == f"tool-{n_tools - 1:05d}")
            ).scalar_one()
        with srv.client() as http:  # the deep page starts after the first half of the fleet
            cursor, seen = None, 0
            while seen < n_tools // 2:
                step = min(500, n_tools // 2 - seen)
                params = {"limit": step, **({"cursor": cursor} if cursor else {})}
                page = http.get("/v1/tools", params=params).json()
                cursor, seen = page["next_cursor"], seen + len(page["items"])
        yield Seeded(url, srv, engine, tool_id, cursor or "", rows, seconds)


# ---- measuring -----------------------------------------------------------------------------


def wrk_latency(url: str, headers: dict[str, str], seconds: int) -> dict[str, float]:
    """wrk -t1 -c1: one request at a time; p50 and p99 in ms and requests/s."""
    args = [_wrk(), "-t1", "-c1", f"-d{seconds}s", "--latency"]
    for k, v in headers.items():
        args += ["-H", f"{k}: {v}"]
    out = subprocess.run([*args, url], check=True, capture_output=True, text=True).stdout
    if "Non-2xx" in out:
        raise RuntimeError(f"non-2xx answers from {url}:\n{out}")

    rps = re.search(r"Requests/sec:\s+([\d.]+)", out)
    assert rps, out
    return {
        "p50_ms": _percentile(out, "50%"),
        "p99_ms": _percentile(out, "99%"),
        "requests_per_s": float(rps.group(1)),
    }


def http_reads(db: Seeded) -> dict[str, tuple[str, dict[str, str]]]:
    auth = {"Authorization": f"Bearer {db.server.admin_key}"}
    base = db.server.url
    return {
        "tcp": (f"{base}/v1/tools/{db.tool_id}/tcp", auth),
        "versions_100": (f"{base}/v1/tools/{db.tool_id}/versions", auth),
        "fleet_first_50": (f"{base}/v1/tools?limit=50", auth),
        "fleet_deep_50": (f"{base}/v1/tools?limit=50&cursor={db.deep_cursor}", auth),
    }


def service_reads(db: Seeded) -> dict[str, Callable[[], object]]:
    """The same reads through the service functions the routers call."""
    bearer = f"Bearer {db.server.admin_key}"

    def tcp() -> object:
        return versions.served_tcp_for_key(
            db.engine, authorization=bearer, tool_id=db.tool_id, fmt=None, if_none_match=None
        )

    def versions_100() -> object:
        with session_scope(write=False, engine=db.engine) as s:
            tool, rows, history = versions.list_versions(s, tool_id=db.tool_id)
            return [versions.version_document(r, tool) for r in rows], history

    def fleet_page(cursor: str | None) -> Callable[[], object]:
        def read() -> object:
            with session_scope(write=False, engine=db.engine) as s:
                return fleet.list_fleet(
                    s,
                    SERVED[0],
                    cell=None,
                    robot_id=None,
                    q=None,
                    status=None,
                    limit=50,
                    cursor=cursor,
                )

        return read

    return {
        "tcp": tcp,
        "versions_100": versions_100,
        "fleet_first_50": fleet_page(None),
        "fleet_deep_50": fleet_page(db.deep_cursor),
    }


def time_call(call: Callable[[], object], n: int) -> float:
    """Median milliseconds of n calls."""
    times = []
    for _ in range(n):
        began = time.perf_counter()
        call()
        times.append((time.perf_counter() - began) * 1e3)
    return median(times)


@contextmanager
def captured(engine: Engine) -> Iterator[list[tuple[str, Any]]]:
    """The statements (and parameters) sent to the database inside the block."""
    sent: list[tuple[str, Any]] = []

    def grab(conn: Any, cursor: Any, statement: str, params: Any, *_: Any) -> None:
        if statement.lstrip().upper().startswith("SELECT"):
            sent.append((statement, params))

    event.listen(engine, "before_cursor_execute", grab)
    try:
        yield sent
    finally:
        event.remove(engine, "before_cursor_execute", grab)


def explain(engine: Engine, statement: str, params: Any) -> list[str]:
    prefix = "EXPLAIN QUERY PLAN " if engine.dialect.name == "sqlite" else "EXPLAIN ANALYZE "
    raw = engine.raw_connection()
    try:
        cur = raw.cursor()
        cur.execute(prefix + statement, params)
        rows = cur.fetchall()
    finally:
        raw.close()
    if engine.dialect.name == "sqlite":
        return [str(r[-1]) for r in rows]
    return [str(r[0]) for r in rows]


LARGE_TABLES = ("tools", "calibrations", "tcp_versions", "activations", "audit_events")


def full_scans(plan: list[str]) -> list[str]:
    """Plan lines that read a whole large table (or the whole of one of its indexes)."""
    bad = []
    sorted_after = any("USE TEMP B-TREE FOR ORDER BY" in line for line in plan)
    for line in plan:
        # SQLite: a table scan, or an index walked whole and then sorted (an index walked in
        # the query's order stops at the LIMIT and is fine).
        sqlite_scan = re.match(r"SCAN (\w+)(?! USING)", line.strip()) or (
            re.match(r"SCAN (\w+)", line.strip()) if sorted_after else None
        )
        pg_scan = re.search(r"Seq Scan on (\w+)", line)
        scan = sqlite_scan or pg_scan
        table = scan.group(1) if scan else None
        if table in LARGE_TABLES:
            bad.append(line.strip())
    return bad


def plans(db: Seeded) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {}
    for name, call in service_reads(db).items():
        with captured(db.engine) as sent:
            call()
        if name == "tcp":  # sent on the held connection, past the engine's events
            digest = hash_key(db.server.admin_key)
            sent.append(
                hot_read.HOT_READ.statement(db.engine, digest=digest, subject_id=db.tool_id)
            )
        out[name] = []
        for statement, params in sent:
            plan = explain(db.engine, statement, params)
            out[name].append(
                {
                    "statement": " ".join(statement.split()),
                    "plan": plan,
                    "full_scans": full_scans(plan),
                }
            )
    return out


def measure(backend: str, n_tools: int, rounds: int, seconds: int, tmp: Path) -> dict[str, Any]:
    logs = Path(tempfile.gettempdir()) / "tcpcal-scale-logs"
    logs.mkdir(exist_ok=True)
    with ExitStack() as stack:
        log = stack.enter_context((logs / f"{backend}.log").open("wb"))
        small = stack.enter_context(seeded(backend, SMALL_TOOLS, tmp, log))
        print(f"{backend}: small seeded {small.rows} in {small.seconds:.1f} s", flush=True)
        large = stack.enter_context(seeded(backend, n_tools, tmp, log))
        print(f"{backend}: large seeded {large.rows} in {large.seconds:.1f} s", flush=True)
        dbs = {"small": small, "large": large}
        http: dict[str, dict[str, list[dict[str, float]]]] = {
            size: {r: [] for r in READS} for size in dbs
        }
        service: dict[str, dict[str, list[float]]] = {size: {r: [] for r in READS} for size in dbs}
        for db in dbs.values():  # warm up: pools, page cache
            for read, (url, headers) in http_reads(db).items():
                wrk_latency(url, headers, 1)
                time_call(service_reads(db)[read], 20)
        for _ in range(rounds):
            for read in READS:
                for size, db in dbs.items():
                    url, headers = http_reads(db)[read]
                    http[size][read].append(wrk_latency(url, headers, seconds))
                    service[size][read].append(time_call(service_reads(db)[read], 200))
        rows = {}
        for read in READS:
            s_http = median(r["p50_ms"] for r in http["small"][read])
            l_http = median(r["p50_ms"] for r in http["large"][read])
            s_svc = median(service["small"][read])
            l_svc = median(service["large"][read])
            rows[read] = {
                "http_p50_ms_small": s_http,
                "http_p50_ms_large": l_http,
                "http_p99_ms_small": median(r["p99_ms"] for r in http["small"][read]),
                "http_p99_ms_large": median(r["p99_ms"] for r in http["large"][read]),
                "http_large_vs_small": l_http / s_http,
                "service_ms_small": s_svc,
                "service_ms_large": l_svc,
                "service_large_vs_small": l_svc / s_svc,
            }
        return {
            "backend": backend,
            "rows_small": small.rows,
            "rows_large": large.rows,
            "seed_seconds_large": large.seconds,
            "reads": rows,
            "plans_large": plans(large),
        }


def markdown(results: list[dict[str, Any]]) -> str:
    lines = [
        "| database | read | HTTP p50 small ms | HTTP p50 large ms | large / small "
        "| service small ms | service large ms | large / small | full scans |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for res in results:
        for read, r in res["reads"].items():
            scans = sum(len(s["full_scans"]) for s in res["plans_large"][read])
            lines.append(
                f"| {res['backend']} | {read} | {r['http_p50_ms_small']:.2f} "
                f"| {r['http_p50_ms_large']:.2f} | {r['http_large_vs_small']:.2f} "
                f"| {r['service_ms_small']:.3f} | {r['service_ms_large']:.3f} "
                f"| {r['service_large_vs_small']:.2f} | {scans} |"
            )
    return "\n".join(lines) + "\n"


def plan_text(results: list[dict[str, Any]]) -> str:
    out = []
    for res in results:
        for read, statements in res["plans_large"].items():
            out.append(f"## {res['backend']}: {read}")
            for s in statements:
                out.append(
                    f"    {s['statement'][:200]}{'...' if len(s['statement']) > 200 else ''}"
                )
                out.extend(f"      {line}" for line in s["plan"])
    return "\n".join(out) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tools", type=int, default=10_000, help="tools in the large database")
    parser.add_argument("--backends", default="sqlite,postgresql")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=int, default=3)
    parser.add_argument("--no-save", action="store_true")
    args = parser.parse_args()
    _wrk()
    backends = [b for b in args.backends.split(",") if b != "postgresql" or _pg_reachable()]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for backend in backends:
            results.append(measure(backend, args.tools, args.rounds, args.seconds, Path(tmp)))
            print(markdown(results[-1:]), flush=True)
    md = markdown(results)
    print(md)
    print(plan_text(results))
    if args.no_save:
        return
    meta = {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "tools_large": args.tools,
        "tools_small": SMALL_TOOLS,
        "versions_per_tool": VERSIONS_PER_TOOL,
        "rounds": args.rounds,
        "seconds": args.seconds,
        "wrk": "-t1 -c1 --latency",
    }
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "scale.json").write_text(
        json.dumps({"meta": meta, "results": results}, indent=2) + "\n"
    )
    (RESULTS / "scale.md").write_text(md + "\n" + plan_text(results))


if __name__ == "__main__":
    main()
