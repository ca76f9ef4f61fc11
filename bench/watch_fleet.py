"""The fleet at scale (issue 50): N simulated KUKA controllers, a pendant edit on every one at
once, and how long until the watcher of 1 or 3 tcpcal instances flags each.

The controllers are KUKAVARPROXY's reads as a KRC answers them (the OpenShowVar framing and
the texts tests/controllers/kuka_sim.py prints for the variables the connector reads, copied
here: a benchmark imports nothing of tests/), served from one asyncio loop in this process,
each on a loopback port of its own, every answer delayed `--latency-ms` (a KRC's
CrossComm): a thread per connection, as the tests' simulators run, would cost the 2 cores
the server is measured on.
Each connection a simulator accepts is one read of its robot (the watcher reads a robot over
one connection), timestamped there.

Each scenario: a fresh database (SQLite for one instance, PostgreSQL for several), migrated and
served by the code of `--tree` (default: this repository; another checkout measures its code:
`git worktree add /tmp/before <commit>`), `tcpcal serve --workers 1` per instance with
TCPCAL_RECONCILE_INTERVAL_S; one robot, controller, tool and calibration made through the
API, copied in bulk to the other robots (each its own simulator's port). Once every tool is
in sync and every robot's live tool read (simulators that serve fewer pose variables than
the connector asks for stop the run there, with the error the rounds stored), the steady
rounds are measured over `--steady-intervals` (2): CPU-seconds of the instances' processes
per robot read, the time from each read of a robot to its next, the machine's busy cores and
each instance's /ready. Then every simulator's tool is edited at once and the database
polled every 0.2 s until each tool is drifted (at most `--watch-intervals`, 6): the seconds
from the edit to each flag, in intervals. `--kill` sends SIGKILL to one instance half an
interval after the edit (mid-round). A robot read twice less than half an interval apart is
a double read.

Run from the repository root with `nice`: `.venv/bin/python -m bench.watch_fleet --robots 1000
--instances 1` (PostgreSQL from TCPCAL_TEST_DATABASE_URL). Writes bench/results/watch_fleet.json
(every run appended, keyed by its label) and bench/results/watch_fleet.md.
"""

from __future__ import annotations

import argparse
import asyncio
import itertools
import json
import os
import platform
import signal
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Awaitable, Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import httpx
from sqlalchemy import MetaData, create_engine, insert, select, text
from sqlalchemy.engine import Engine

from testbed.databases import fresh_database

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "bench" / "results"
PG_URL = os.environ.get("TCPCAL_TEST_DATABASE_URL")
SLOT = 1
ACTIVE = (10.0, 20.0, 150.0)
#: How far each edit moves the tool (mm): drifted beyond the 0.01 mm tolerance.
EDIT_MM = 0.5
#: The tables copied from the template robot, parents first.
COPIED = ("robots", "robot_controllers", "tools", "calibrations", "tcp_versions", "activations")
POLL_S = 0.2


# ---- simulators ----------------------------------------------------------------------------


#: What the KRC prints for each variable the connector reads (tests/controllers/kuka_sim.py's
#: texts for tool 1 at ACTIVE and the robot standing as that simulator starts).
VARIABLES = {
    "$LOAD_DATA[1]": "{LOAD: M -1.0, CM {FRAME: X 0.0, Y 0.0, Z 0.0, A 0.0, B 0.0, C 0.0}, "
    "J {INERTIA: X 0.0, Y 0.0, Z 0.0}}",
    "$POS_ACT": "{E6POS: X 1000.0, Y 0.0, Z 1000.0, A 0.0, B 0.0, C 0.0, S 2, T 2, E1 0.0, "
    "E2 0.0, E3 0.0, E4 0.0, E5 0.0, E6 0.0}",
    "$AXIS_ACT": "{E6AXIS: A1 0.0, A2 -90.0, A3 90.0, A4 0.0, A5 0.0, A6 0.0, E1 0.0, E2 0.0, "
    "E3 0.0, E4 0.0, E5 0.0, E6 0.0}",
    "$TOOL": "{FRAME: X 0.0, Y 0.0, Z 0.0, A 0.0, B 0.0, C 0.0}",
    "$BASE": "{FRAME: X 0.0, Y 0.0, Z 0.0, A 0.0, B 0.0, C 0.0}",
    "$ROBROOT_C": "{FRAME: X 0.0, Y 0.0, Z 0.0, A 0.0, B 0.0, C 0.0}",
    "$ACT_TOOL": "-1",
    "$ACT_BASE": "-1",
    "$IPO_MODE": "#BASE",
}


def _tool_text(y: float) -> str:
    x, _, z = ACTIVE
    return f"{{FRAME: X {x}, Y {y}, Z {z}, A 0.0, B 0.0, C 0.0}}"


@dataclass
class Sim:
    """One simulated controller: its tool 1 as printed and when it accepted a connection."""

    tool: str = field(default_factory=lambda: _tool_text(ACTIVE[1]))
    port: int = 0
    accepted: list[float] = field(default_factory=list)

    def answer(self, msg_id: int, body: bytes) -> bytes:
        """KUKAVARPROXY's reply to a read (mode 0): the value, 0x00 0x01, ok; a variable
        the KRC cannot show is an empty value with ok = 1; anything else is refused."""
        mode = body[0]
        (size,) = struct.unpack("!H", body[1:3])
        name = body[3 : 3 + size].decode("latin-1").strip().upper()
        text_ = self.tool if name == f"$TOOL_DATA[{SLOT}]" else VARIABLES.get(name, "")
        raw = text_.encode("latin-1")
        ok = int(mode == 0)
        reply = bytes([mode]) + struct.pack("!H", len(raw)) + raw + b"\x00\x01" + bytes([ok])
        return struct.pack("!HH", msg_id, len(reply)) + reply


class Fleet:
    """N KUKAVARPROXY simulators served by one asyncio loop in a thread of this process."""

    def __init__(self, n: int, latency_s: float) -> None:
        self.latency_s = latency_s
        self.sims = [Sim() for _ in range(n)]
        self._loop = asyncio.new_event_loop()
        self._servers: list[asyncio.Server] = []
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> Fleet:
        self._thread.start()
        if not self._ready.wait(120):
            raise RuntimeError("the simulators did not start within 120 s")
        return self

    def __exit__(self, *exc: object) -> None:
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._loop.run_until_complete(self._start())
        self._ready.set()
        self._loop.run_forever()
        for server in self._servers:
            server.close()

    async def _start(self) -> None:
        for sim in self.sims:
            server = await asyncio.start_server(self._handler(sim), "127.0.0.1", 0, backlog=64)
            sim.port = server.sockets[0].getsockname()[1]
            self._servers.append(server)

    def _handler(self, sim: Sim) -> Callable[[asyncio.StreamReader, Any], Awaitable[None]]:
        async def handle(reader: asyncio.StreamReader, writer: Any) -> None:
            await self._serve(sim, reader, writer)

        return handle

    async def _serve(self, sim: Sim, reader: asyncio.StreamReader, writer: Any) -> None:
        sim.accepted.append(time.monotonic())
        try:
            while True:
                head = await reader.readexactly(4)
                msg_id, length = struct.unpack("!HH", head)
                body = await reader.readexactly(length)
                answer = sim.answer(msg_id, body)
                await asyncio.sleep(self.latency_s)
                writer.write(answer)
                await writer.drain()
        except (asyncio.IncompleteReadError, ConnectionError, OSError):
            pass
        finally:
            writer.close()

    def edit_all(self) -> float:
        """The pendant edit on every controller; when it was done (monotonic)."""
        edited = _tool_text(ACTIVE[1] + EDIT_MM)
        for sim in self.sims:
            sim.tool = edited
        return time.monotonic()

    def reads(self, since: float, until: float) -> int:
        return sum(1 for sim in self.sims for t in list(sim.accepted) if since <= t < until)

    def read_gaps(self, since: float, until: float) -> list[float]:
        """The time from each read of a robot to its next (seconds), every robot's."""
        gaps: list[float] = []
        for sim in self.sims:
            times = [t for t in list(sim.accepted) if since <= t < until]
            gaps.extend(b - a for a, b in itertools.pairwise(times))
        return gaps

    def double_reads(self, since: float, until: float, apart_s: float) -> int:
        """Reads of a robot that followed its previous read by less than `apart_s`."""
        doubles = 0
        for sim in self.sims:
            times = [t for t in list(sim.accepted) if since <= t < until]
            doubles += sum(1 for a, b in itertools.pairwise(times) if b - a < apart_s)
        return doubles


# ---- instances -----------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _in_tree(tree: Path, code: str, *args: str) -> str:
    """Run Python `code` with `tree`'s app/ (its first sys.path entry); its stdout."""
    done = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=tree,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-3000:])
    return done.stdout.strip()


def prepare(tree: Path, url: str) -> str:
    """Migrate the database with the tree's migrations; an admin key made by its code."""
    return _in_tree(
        tree,
        "import sys\n"
        "from app.storage.migrate import upgrade\n"
        "from app.services.keys import create_key\n"
        "from app.storage.db import make_engine, session_scope\n"
        "upgrade(sys.argv[1])\n"
        "engine = make_engine(sys.argv[1])\n"
        "with session_scope(write=True, engine=engine) as s:\n"
        "    _, key = create_key(s, name='bench', scope='admin', actor=None)\n"
        "print(key)\n",
        url,
    )


@dataclass
class Instance:
    url: str
    process: subprocess.Popen[bytes]
    log: IO[bytes]

    def cpu_s(self) -> float:
        """CPU-seconds (user + system) of the instance's process and its children so far."""
        return sum(_cpu_of(pid) for pid in _tree_pids(self.process.pid))


def _machine_busy_s() -> float:
    """CPU-seconds every core of the machine has spent not idle so far (/proc/stat)."""
    fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    idle = fields[3] + fields[4]  # idle, iowait
    return (sum(fields[:8]) - idle) / os.sysconf("SC_CLK_TCK")


def _own_cpu_s() -> float:
    """CPU-seconds this process (every thread) has spent so far."""
    times = os.times()
    return times.user + times.system


def _postgres_cpu_s() -> float:
    """CPU-seconds the machine's PostgreSQL processes have spent so far (0 without them)."""
    total = 0.0
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            head = stat.read_text()
        except OSError:
            continue
        if "(postgres)" in head:
            total += _cpu_of(int(stat.parent.name))
    return total


def _watcher_of(inst: Instance) -> dict[str, Any] | None:
    """What the instance's /ready says of its watcher (None: it did not answer)."""
    try:
        return dict(httpx.get(f"{inst.url}/ready", timeout=5.0).json()["watcher"])
    except (httpx.HTTPError, KeyError, ValueError):
        return None


def _tree_pids(root: int) -> list[int]:
    pids, todo = [], [root]
    while todo:
        pid = todo.pop()
        pids.append(pid)
        try:
            kids = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
        except OSError:
            continue
        todo.extend(int(k) for k in kids)
    return pids


def _cpu_of(pid: int) -> float:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@contextmanager
def instances(
    tree: Path, url: str, n: int, interval_s: float, tmp: Path, extra_env: dict[str, str]
) -> Iterator[list[Instance]]:
    started: list[Instance] = []
    env = {
        **os.environ,
        "TCPCAL_DATABASE_URL": url,
        "TCPCAL_RECONCILE_INTERVAL_S": str(interval_s),
        "TCPCAL_SOLVE_PROCESSES": "0",
        "TCPCAL_LOG_FORMAT": "json",
        **extra_env,
    }
    try:
        for i in range(n):
            port = _free_port()
            log = (tmp / f"instance{i}.log").open("w+b")
            proc = subprocess.Popen(
                [
                    sys.executable,
                    "-c",
                    "from app.cli import main; main()",
                    "serve",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    str(port),
                    "--workers",
                    "1",
                ],
                cwd=tree,
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
            started.append(Instance(f"http://127.0.0.1:{port}", proc, log))
        for inst in started:
            _wait_ready(inst)
        yield started
    finally:
        for inst in started:
            if inst.process.poll() is None:
                os.killpg(inst.process.pid, signal.SIGTERM)
        for inst in started:
            try:
                inst.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(inst.process.pid, signal.SIGKILL)
                inst.process.wait()
            inst.log.close()


def _wait_ready(inst: Instance) -> None:
    deadline = time.monotonic() + 120
    with httpx.Client(timeout=2) as http:
        while time.monotonic() < deadline:
            if inst.process.poll() is not None:
                inst.log.seek(0)
                raise RuntimeError(f"instance exited:\n{inst.log.read().decode()[-3000:]}")
            try:
                if http.get(f"{inst.url}/ready").status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.2)
    raise RuntimeError("an instance was not ready within 120 s")


# ---- the fleet in the database -------------------------------------------------------------


def template(inst: Instance, key: str, port: int) -> dict[str, str]:
    """One robot with a KUKA controller at `port`, a tool in SLOT and its active version."""
    headers = {"Authorization": f"Bearer {key}"}
    with httpx.Client(base_url=inst.url, headers=headers, timeout=60) as http:
        robot = http.post("/v1/robots", json={"name": "r0", "cell": "bench"}).json()
        body = {"protocol": "kuka_kvp", "host": "127.0.0.1", "port": port, "timeout_s": 3.0}
        put = http.put(f"/v1/robots/{robot['id']}/controller", json=body)
        put.raise_for_status()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "t", "slot": SLOT})
        tool.raise_for_status()
        calibration = {
            "method": "manual",
            "tcp": {"position_mm": list(ACTIVE), "quaternion": [1.0, 0.0, 0.0, 0.0]},
        }
        done = http.post(f"/v1/tools/{tool.json()['id']}/calibrations", json=calibration)
        done.raise_for_status()
        return {"robot": robot["id"], "tool": tool.json()["id"], "calibration": done.json()["id"]}


def copy_fleet(engine: Engine, made: dict[str, str], ports: list[int]) -> None:
    """Copy the template's rows for each further port: every id of the template's robot,
    tool and calibration replaced by a new one, the robot's name and controller port its
    own (rows read and written through reflected tables: any revision's schema)."""
    meta = MetaData()
    meta.reflect(engine, only=list(COPIED))
    with engine.begin() as conn:
        # only the template is in these tables yet
        rows = {
            name: [dict(r._mapping) for r in conn.execute(select(meta.tables[name]))]
            for name in COPIED
        }
        # every id a copied row has (a string), each copy's own
        ids = {r["id"] for found in rows.values() for r in found if isinstance(r.get("id"), str)}
        ids |= set(made.values())
        for start in range(0, len(ports), 500):
            batch: dict[str, list[dict[str, Any]]] = {name: [] for name in COPIED}
            for i, port in enumerate(ports[start : start + 500], start=start + 1):
                new = {value: _new_id(value) for value in ids}
                for name in COPIED:
                    for row in rows[name]:
                        copy = {
                            k: new.get(v, v) if isinstance(v, str) else v for k, v in row.items()
                        }
                        if isinstance(copy.get("id"), int):
                            copy.pop("id")
                        if name == "robots":
                            copy["name"] = f"r{i}"
                        if name == "robot_controllers":
                            copy["port"] = port
                        batch[name].append(copy)
            for name in COPIED:
                conn.execute(insert(meta.tables[name]), batch[name])


def _new_id(like: str) -> str:
    return str(uuid.uuid4()) if "-" in like else uuid.uuid4().hex


def states(engine: Engine) -> dict[str, str]:
    with engine.connect() as conn:
        return {
            r.tool_id: r.state
            for r in conn.execute(text("SELECT tool_id, state FROM tool_controller_states"))
        }


def live_read(engine: Engine) -> dict[str, Any]:
    """How many robots' live tool the last round read, and the first error stored."""
    with engine.connect() as conn:
        rows = conn.execute(text("SELECT read, error FROM robot_live_tools")).all()
    errors = [r.error for r in rows if r.error]
    return {"read": sum(1 for r in rows if r.read), "error": errors[0] if errors else None}


def wait_all(engine: Engine, n: int, state: str, within_s: float) -> float | None:
    """Seconds until `n` tools are in `state` (None: not within `within_s`)."""
    start = time.monotonic()
    while time.monotonic() - start < within_s:
        if sum(1 for s in states(engine).values() if s == state) >= n:
            return time.monotonic() - start
        time.sleep(0.5)
    return None


# ---- a scenario ----------------------------------------------------------------------------


def run(args: argparse.Namespace) -> dict[str, Any]:
    backend = "postgresql" if args.instances > 1 or args.backend == "postgresql" else "sqlite"
    interval = args.interval
    tree = Path(args.tree).resolve()
    out: dict[str, Any] = {
        "label": args.label,
        "tree": str(tree),
        "commit": args.commit or _git_head(tree),
        "robots": args.robots,
        "instances": args.instances,
        "backend": backend,
        "latency_ms": args.latency_ms,
        "interval_s": interval,
        "kill": args.kill,
        "load_before": os.getloadavg(),
    }
    with ExitStack() as stack:
        tmp = Path(stack.enter_context(tempfile.TemporaryDirectory()))
        url = stack.enter_context(fresh_database(backend, tmp, PG_URL, prefix="watchfleet"))
        key = prepare(tree, url)
        fleet = stack.enter_context(Fleet(args.robots, args.latency_ms / 1000))
        env = dict(kv.split("=", 1) for kv in args.env)
        insts = stack.enter_context(instances(tree, url, args.instances, interval, tmp, env))
        engine = create_engine(url)
        stack.callback(engine.dispose)
        made = template(insts[0], key, fleet.sims[0].port)
        copy_fleet(engine, made, [sim.port for sim in fleet.sims[1:]])
        synced = wait_all(engine, args.robots, "in_sync", 15 * interval + 30)
        out["in_sync_after_s"] = synced
        if synced is None:
            out["error"] = f"not every tool in sync: {_count(states(engine))}"
            return out
        out["live_tool_read"] = live_read(engine)
        if out["live_tool_read"]["read"] < args.robots:
            # a pose variable the simulators do not serve (the connector asks for more):
            # every round would store an error instead of the tool the robot moves by
            out["error"] = f"the live tool not read on every robot: {out['live_tool_read']}"
            return out
        # the steady rounds: CPU per robot read over `--steady-intervals` intervals
        cpu0, busy0, t0 = sum(i.cpu_s() for i in insts), _machine_busy_s(), time.monotonic()
        own0, db0 = _own_cpu_s(), _postgres_cpu_s()
        time.sleep(args.steady_intervals * interval)
        cpu1, busy1, t1 = sum(i.cpu_s() for i in insts), _machine_busy_s(), time.monotonic()
        own1, db1 = _own_cpu_s(), _postgres_cpu_s()
        reads = fleet.reads(t0, t1)
        out["steady"] = {
            "seconds": round(t1 - t0, 2),
            "reads": reads,
            "reads_per_robot_per_interval": round(reads / args.robots / ((t1 - t0) / interval), 3),
            "cpu_s": round(cpu1 - cpu0, 2),
            "cpu_ms_per_read": round(1000 * (cpu1 - cpu0) / max(reads, 1), 2),
            "double_reads": fleet.double_reads(t0, t1, interval / 2),
            "read_gap_s": _spread(fleet.read_gaps(t0, t1)),
            # the machine's cores busy (of its CPUs), the simulators and the database included
            "machine_busy_cores": round((busy1 - busy0) / (t1 - t0), 2),
            # of them: this process (the simulators, the database polls) and PostgreSQL's
            "bench_cores": round((own1 - own0) / (t1 - t0), 2),
            "postgres_cores": round((db1 - db0) / (t1 - t0), 2),
            "watchers": [_watcher_of(i) for i in insts],
        }
        out["edit"] = edit_and_watch(fleet, engine, insts, interval, args)
        out["overrun_lines"] = sum(_overruns(i) for i in insts)
        out["load_after"] = os.getloadavg()
    return out


def edit_and_watch(
    fleet: Fleet, engine: Engine, insts: list[Instance], interval: float, args: argparse.Namespace
) -> dict[str, Any]:
    with engine.connect() as conn:
        rows = conn.execute(
            text(
                "SELECT rc.port, t.id FROM robot_controllers rc JOIN tools t "
                "ON t.robot_id = rc.robot_id"
            )
        ).all()
    tool_of: dict[int, str] = {int(port): str(tool_id) for port, tool_id in rows}
    edited = fleet.edit_all()
    killed_at = None
    flagged: dict[str, float] = {}
    deadline = edited + args.watch_intervals * interval
    while time.monotonic() < deadline and len(flagged) < args.robots:
        if args.kill and killed_at is None and time.monotonic() - edited >= interval / 2:
            os.killpg(insts[-1].process.pid, signal.SIGKILL)
            killed_at = time.monotonic() - edited
        now = time.monotonic() - edited
        for tool_id, state in states(engine).items():
            if state == "drifted" and tool_id not in flagged:
                flagged[tool_id] = now
        time.sleep(POLL_S)
    delays = sorted(flagged.values())
    end = time.monotonic()
    per_sim = [sum(1 for t in sim.accepted if edited <= t < end) for sim in fleet.sims]
    missing = [p for p, t in tool_of.items() if t not in flagged]
    return {
        "flagged": len(flagged),
        "not_flagged": len(missing),
        "killed_at_s": None if killed_at is None else round(killed_at, 2),
        "median_s": round(statistics.median(delays), 2) if delays else None,
        "p99_s": round(delays[int(0.99 * (len(delays) - 1))], 2) if delays else None,
        "last_s": round(delays[-1], 2) if delays else None,
        "last_intervals": round(delays[-1] / interval, 2) if delays else None,
        "within_one_interval": sum(1 for d in delays if d <= interval),
        "within_two_intervals": sum(1 for d in delays if d <= 2 * interval),
        "reads_per_robot_after_edit": {"min": min(per_sim), "max": max(per_sim)},
        "double_reads_after_edit": fleet.double_reads(edited, end, interval / 2),
        "watched_s": round(end - edited, 1),
    }


def _spread(values: list[float]) -> dict[str, float] | None:
    """The median and the longest of `values` (None for none)."""
    if not values:
        return None
    return {"median": round(statistics.median(values), 3), "max": round(max(values), 3)}


def _git_head(tree: Path) -> str:
    done = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"],
        cwd=tree,
        capture_output=True,
        text=True,
        check=False,
    )
    return done.stdout.strip() or "?"


def _count(found: dict[str, str]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for state in found.values():
        counts[state] = counts.get(state, 0) + 1
    return counts


def _overruns(inst: Instance) -> int:
    inst.log.flush()
    inst.log.seek(0)
    return inst.log.read().count(b"watcher.round_overrun")


# ---- output --------------------------------------------------------------------------------


def markdown(runs: list[dict[str, Any]]) -> str:
    lines = [
        "# The fleet at scale: a pendant edit on every simulated robot, flagged by the watcher",
        "",
        "`.venv/bin/python -m bench.watch_fleet` (bench/watch_fleet.py says what is measured).",
        "",
        "| run | commit | robots | inst | db | reply ms | interval s | kill | in sync s "
        "| CPU ms/read | server CPU s (steady) | reads/robot/interval | read gap s (median / max) "
        "| flagged | last s (intervals) | within 1 / 2 intervals | double reads | overrun lines "
        "| load |",
        "|" + "---|" * 19,
    ]
    for r in runs:
        s, e = r.get("steady", {}), r.get("edit", {})
        last = f"{e.get('last_s')} ({e.get('last_intervals')})" if e else "-"
        gap = s.get("read_gap_s")
        gaps = "-" if not gap else f"{gap['median']} / {gap['max']}"
        lines.append(
            f"| {r['label']} | {r['commit']} | {r['robots']} | {r['instances']} | {r['backend']} "
            f"| {r['latency_ms']} | {r['interval_s']} | {'yes' if r['kill'] else 'no'} "
            f"| {r.get('in_sync_after_s') and round(r['in_sync_after_s'], 1)} "
            f"| {s.get('cpu_ms_per_read')} | {s.get('cpu_s')} "
            f"| {s.get('reads_per_robot_per_interval')} | {gaps} "
            f"| {e.get('flagged')}/{r['robots']} | {last} "
            f"| {e.get('within_one_interval')} / {e.get('within_two_intervals')} "
            f"| {s.get('double_reads')} + {e.get('double_reads_after_edit')} "
            f"| {r.get('overrun_lines')} "
            f"| {round(r['load_before'][0], 1)}-{round(r.get('load_after', [0])[0], 1)} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--label", required=True)
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--instances", type=int, default=1)
    parser.add_argument("--backend", choices=["sqlite", "postgresql"], default="sqlite")
    parser.add_argument("--latency-ms", type=float, default=20.0)
    parser.add_argument("--interval", type=float, default=10.0)
    parser.add_argument("--watch-intervals", type=float, default=6.0)
    parser.add_argument(
        "--steady-intervals",
        type=float,
        default=2.0,
        help="intervals the steady rounds' CPU per read is measured over",
    )
    parser.add_argument("--kill", action="store_true", help="SIGKILL one instance mid-round")
    parser.add_argument("--tree", default=str(REPO), help="the checkout whose code serves")
    parser.add_argument("--commit", default=None, help="the tree's commit (default: its git)")
    parser.add_argument("--env", action="append", default=[], help="NAME=VALUE for instances")
    args = parser.parse_args()
    if args.robots > 5000 or args.instances > 5:
        parser.error("at most 5000 robots and 5 instances (a bench on a shared machine)")
    result = run(args)
    result["machine"] = {"cpus": os.cpu_count(), "python": platform.python_version()}
    print(json.dumps(result, indent=2))
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "watch_fleet.json"
    runs = json.loads(path.read_text())["runs"] if path.exists() else []
    runs = [r for r in runs if r["label"] != args.label] + [result]
    path.write_text(json.dumps({"runs": runs}, indent=2) + "\n")
    (RESULTS / "watch_fleet.md").write_text(markdown(runs))


if __name__ == "__main__":
    main()
