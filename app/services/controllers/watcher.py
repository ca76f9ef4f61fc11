"""The watcher: with TCPCAL_RECONCILE_INTERVAL_S > 0, every robot that has a controller is
reconciled that often.

Each server process runs one watcher thread (started and stopped by the app's lifespan). On
PostgreSQL the instances share the rounds by leases (app.services.controllers.leases): every
tick each claims its share of the robots due and reads them, each robot by exactly one
instance a round. On SQLite one instance watches: before a round it takes the fleet's
watcher lock without waiting, an flock of `<database>-watcher.lock` next to the file (as
app.storage.db queues SQLite's writers); whoever does not get it skips the round (`round()`,
which takes PostgreSQL's `pg_try_advisory_lock` there, is what a direct call runs).

A robot's round reads every deployed subject of it (its tools, then the other subjects that
declare a controller side) over one connection (app.services.controllers.reconcile). The
states it finds are stored under each subject's row lock (app.services.controllers.states),
so a change is recorded once even if two rounds met.

A round reads its robots' controllers concurrently (a ReadPool of daemon threads), as many
at once as its robots need for their reads to end within half the interval and at least
TCPCAL_RECONCILE_CONCURRENCY; a read that has stalled holds no place (issue 51: ten hung
controllers filled a fixed pool of 8 and held a healthy robot's edit 1.0-7.2 s). Each
robot's states are stored as soon as its own read ends: read one by one, a controller that
hung for its timeout_s (30 s in the trial) delayed every other robot's state change by as
much. A robot whose read is still in flight is not read again by the next round (no pile-up
of threads or connections on a hung controller), and while any read is in flight the fleet
lock stays held into the next round, so no other instance starts those controllers
meanwhile.
The threads are daemons: stop() returns within a second, and a read stalled on a controller
ends at that controller's timeout, storing nothing.

The interval is the most time from a change at a controller to its record (issue 50: read
once an interval, a change made just after a robot's read waited the interval for the next
and was recorded that read and its store later, 1.35-1.39 intervals for the last of 2000
robots on 3 instances). Each robot is read again one period after its last read began: the
interval less its lead, the longest time the last reads took from their offer (on
PostgreSQL, their due time: a tick before) to their states stored, at most LEAD_SHARE of
the interval (period_after). A SQLite round offers its robots evenly over SPREAD of its period,
so each is offered one period after its last offer and waits little for a place; on
PostgreSQL a claim makes its robot due one period on, and the ticks claim as the pool can
read.
"""

from __future__ import annotations

import logging
import math
import os
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future
from contextlib import ExitStack, contextmanager, suppress
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import IO

try:
    import fcntl
except ImportError:  # Windows: no flock; one process per database there
    fcntl = None  # type: ignore[assignment]

from sqlalchemy import text

from app.config import get_settings
from app.errors import ConnectorMissing
from app.logs import get_logger
from app.metrics import (
    WATCHED_ROBOTS,
    WATCHER_CONCURRENCY,
    WATCHER_INTERVAL_NEEDED,
    WATCHER_OVERRUNS,
    WATCHER_ROUND_SECONDS,
)
from app.schemas.controllers import Reconciliation
from app.security.auth import Principal
from app.services.controllers.leases import Leases, Tick
from app.services.controllers.reconcile import (
    RoundRead,
    reconcile_robot,
    robots_with_controller,
    store_rounds,
)
from app.storage.db import get_engine, is_sqlite
from app.storage.models import utcnow

log = logging.getLogger("tcpcal.watcher")
#: The same logger's structured lines (an event and its fields).
events = get_logger("tcpcal.watcher")

#: Who the watcher's audit events name.
WATCHER = Principal(key_id="watcher", name="watcher", scope="read")
#: The advisory lock's key on PostgreSQL ("tcpcal.watcher" as a 64-bit number).
ADVISORY_KEY = int.from_bytes(b"tcpcal.w", "big") & 0x7FFF_FFFF_FFFF_FFFF

_THREADS_LOCK = threading.Lock()
#: A read still going this long (seconds) no longer holds a place of the pool, until the
#: watcher has measured its fleet's reads (then 4 times their median, 0.25 s to half the
#: interval).
STALL_S = 1.0
#: The time a read is taken to take before any has been measured (seconds).
FIRST_READ_S = 0.5
#: The most robots' rounds one write transaction stores: each reader waits for its batch, so
#: a batch is also how long a read's thread is held after it. bench.watch_fleet, 300 robots
#: on SQLite at load 13-19: 200 a batch read each robot 0.69 times a round (11.6 ms of CPU a
#: read), 50 a batch 1.0 times (6.0 ms), every edit flagged within 1.08 intervals.
STORE_BATCH = 50
#: The most threads reading at once that the pool is sized to (stalled reads apart): 1000
#: robots of 0.25 s at a 10 s interval need 50. On a machine short of CPU a read's wall time
#: grows with the threads that share the cores, and a pool sized from it grew to 256 threads
#: an instance (3 instances, 2000 robots, load 18 on 2 cores: 21.4 ms of CPU a read against
#: 14.0 ms for one watcher); more threads read no faster there.
MAX_SIZE = 64
#: The share of its period over which a SQLite round offers its robots, evenly in their order:
#: at the pool's size (reads ending within half the interval) the reads begin as they are
#: offered (an eighth of the pool to spare at a period of 0.95 interval, none once the lead
#: takes LEAD_SHARE of it), so a robot's offer-to-stored time, the lead its period leaves, is
#: its read and store, not the fleet's queue.
SPREAD = 0.6
#: The most of the interval a robot's lead takes from its period: a machine short of CPU
#: lengthens every read, and a lead of half the interval read each robot twice an interval
#: (two instances sharing 6 robots at a 1 s interval under a test suite's load), adding the
#: load that lengthened them; at a quarter a robot is read at most 4/3 times an interval,
#: and a lead beyond it is a change recorded that much after the interval.
LEAD_SHARE = 0.25
#: Offers due within this long (seconds) are made together (a SQLite round's pacing).
PACE_S = 0.02


@contextmanager
def fleet_lock() -> Iterator[bool]:
    """Try to take the fleet's watcher lock without waiting; yields whether it was taken."""
    engine = get_engine()
    if not is_sqlite(engine):
        with engine.connect() as conn:
            taken = bool(
                conn.execute(text("SELECT pg_try_advisory_lock(:k)"), {"k": ADVISORY_KEY}).scalar()
            )
            conn.commit()
            try:
                yield taken
            finally:
                if taken:
                    conn.execute(text("SELECT pg_advisory_unlock(:k)"), {"k": ADVISORY_KEY})
                    conn.commit()
        return
    database = engine.url.database or ""
    if not _THREADS_LOCK.acquire(blocking=False):
        yield False
        return
    try:
        if fcntl is None or database in ("", ":memory:") or database.startswith("file:"):
            yield True
            return
        with _flock(Path(f"{database}-watcher.lock")) as taken:
            yield taken
    finally:
        _THREADS_LOCK.release()


@contextmanager
def _flock(path: Path) -> Iterator[bool]:
    handle: IO[bytes] = path.open("ab")
    try:
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(handle.fileno(), fcntl.LOCK_UN)
    finally:
        handle.close()


class ReadPool:
    """Daemon threads, each reconciling one robot at a time, `size` of them reading at once,
    not counting reads that have stalled. A robot is in flight from when it is offered until
    its read has ended and its states are stored; offering it again meanwhile does nothing,
    so a hung controller is read once, not once per round.

    A read still going `stall_s` after it began stops holding a place: another thread takes
    the next robot queued (issue 51: ten controllers that accept and never answer held all 8
    places of a fixed pool until their timeout_s, and a healthy robot's pendant edit waited
    1.0-7.2 s behind them). The threads are at most one per robot in flight; one that ends
    its read with more threads about than the pool needs ends too."""

    def __init__(self, size: int, work: Callable[[str], None], *, stall_s: float = STALL_S) -> None:
        self.size = size
        self.stall_s = stall_s
        self._work = work
        self._queue: deque[str] = deque()
        #: robot -> when its read began (monotonic), while it reads
        self._reading: dict[str, float] = {}
        self._changed = threading.Condition()
        self._threads = 0
        self._idle = 0
        self._started = 0
        self._stopped = False
        #: how long the last reads that did not stall took (seconds), newest last
        self.read_s: deque[float] = deque(maxlen=256)
        #: robot -> when it was offered (monotonic): the robots in flight (queued or read)
        self._in_flight: dict[str, float] = {}
        #: how long the last reads that did not stall took from their offer to their end,
        #: their states stored (seconds): the wait for a place, the read and the store
        self.settle_s: deque[float] = deque(maxlen=256)

    def resize(self, size: int) -> None:
        """Read up to `size` robots at once from now on."""
        with self._changed:
            self.size = size
            self._top_up()

    def offer(self, robot_ids: Iterable[str]) -> set[str]:
        """Queue each of these robots that is not in flight; the ones queued now."""
        with self._changed:
            if self._stopped:
                return set()
            fresh = [robot_id for robot_id in robot_ids if robot_id not in self._in_flight]
            now = time.monotonic()
            self._in_flight.update((robot_id, now) for robot_id in fresh)
            self._queue.extend(fresh)
            self._top_up()
            self._changed.notify_all()
        return set(fresh)

    def in_flight(self) -> int:
        """How many robots are queued or being read."""
        with self._changed:
            return len(self._in_flight)

    def in_flight_ids(self) -> set[str]:
        """The robots queued or being read."""
        with self._changed:
            return set(self._in_flight)

    def waiting(self) -> int:
        """How many robots are queued, their reads not begun."""
        with self._changed:
            return len(self._queue)

    def serve_for(self, seconds: float) -> None:
        """Wait `seconds` (less if the pool stops), handing stalled reads' places on."""
        until = time.monotonic() + seconds
        with self._changed:
            while not self._stopped:
                now = time.monotonic()
                if now >= until:
                    return
                self._top_up()
                self._changed.wait(min(until - now, self._next_stall(now)))

    def queued(self, robot_ids: set[str]) -> int:
        """How many of these robots wait for a read that has not begun."""
        with self._changed:
            return sum(1 for robot_id in self._queue if robot_id in robot_ids)

    def longest_settle_s(self) -> float | None:
        """The longest of the last reads that did not stall, from its offer to its states
        stored (None before the first)."""
        with self._changed:
            return max(self.settle_s) if self.settle_s else None

    def median_read_s(self) -> float | None:
        """The median of the last reads that did not stall (None before the first)."""
        with self._changed:
            return statistics.median(self.read_s) if self.read_s else None

    def stalled(self) -> int:
        """How many reads have gone on for `stall_s` or longer."""
        with self._changed:
            return self._stalled(time.monotonic())

    def threads(self) -> int:
        """How many threads the pool has now."""
        with self._changed:
            return self._threads

    def wait(self, robot_ids: set[str], timeout_s: float) -> bool:
        """Wait up to `timeout_s` until none of these robots is in flight (or the pool
        stopped); whether that happened. Meanwhile a read that stalls hands its place on."""
        until = time.monotonic() + timeout_s
        with self._changed:
            while True:
                if self._stopped or not robot_ids & self._in_flight.keys():
                    return True
                now = time.monotonic()
                if now >= until:
                    return False
                self._top_up()
                self._changed.wait(min(until - now, self._next_stall(now)))

    def stop(self) -> None:
        """Take no more work; idle threads end now, busy ones when their read ends."""
        with self._changed:
            self._stopped = True
            self._queue.clear()
            self._changed.notify_all()

    def join(self, until: float) -> None:
        """Wait for the threads to end, until the monotonic time `until` at the latest."""
        with self._changed:
            while self._threads and time.monotonic() < until:
                self._changed.wait(max(0.0, until - time.monotonic()))

    def _stalled(self, now: float) -> int:
        return sum(1 for began in self._reading.values() if now - began >= self.stall_s)

    def _next_stall(self, now: float) -> float:
        """Seconds until the next read in progress stalls (at least 10 ms)."""
        fresh = [b + self.stall_s - now for b in self._reading.values() if now - b < self.stall_s]
        return max(0.01, min(fresh, default=self.stall_s))

    def _top_up(self) -> None:
        """Start threads for the queued robots: `size` reading at once, stalled reads apart
        (called holding the condition)."""
        if self._stopped:
            return
        reading = len(self._reading) - self._stalled(time.monotonic())
        wanted = min(len(self._queue), max(0, self.size - reading)) - self._idle
        for _ in range(max(0, wanted)):
            self._started += 1
            self._threads += 1
            self._idle += 1
            thread = threading.Thread(
                target=self._run, name=f"tcpcal-reconcile-{self._started}", daemon=True
            )
            thread.start()

    def _take(self) -> str | None:
        """The next robot to read, or None when this thread should end (held condition)."""
        while not self._stopped:
            now = time.monotonic()
            if self._queue and len(self._reading) - self._stalled(now) < self.size:
                robot_id = self._queue.popleft()
                self._reading[robot_id] = now
                self._idle -= 1
                return robot_id
            if self._idle > max(0, self.size - len(self._reading)):
                return None  # more threads waiting than places left: end this one
            self._changed.wait(max(0.01, self._next_stall(now)) if self._queue else None)
        return None

    def _run(self) -> None:
        with self._changed:
            robot_id = self._take()
        while robot_id is not None:
            try:
                self._work(robot_id)
            except BaseException:  # a pool strands no robot: the next is taken all the same
                log.exception("reading robot %s failed", robot_id)
            finally:
                with self._changed:
                    began = self._reading.pop(robot_id)
                    ended = time.monotonic()
                    offered = self._in_flight.pop(robot_id)
                    if ended - began < self.stall_s:
                        self.read_s.append(ended - began)
                        self.settle_s.append(ended - offered)
                    self._idle += 1
                    self._changed.notify_all()
            with self._changed:
                robot_id = self._take()
        with self._changed:
            self._threads -= 1
            self._idle -= 1
            self._changed.notify_all()


class StoreBatches:
    """The round's stores: each read that ends is handed here and stored, with the reads that
    ended meanwhile, in one write transaction (app.services.controllers.reconcile
    .store_rounds) by one thread; the reading thread waits for its own. A write transaction
    a robot, on SQLite each queued behind every other writer, stored about 9 robots a second
    on a loaded machine, well below a 1000-robot fleet's 100 a second at a 10 s interval."""

    def __init__(self, actor: Principal, trigger: str) -> None:
        self._actor = actor
        self._trigger = trigger
        self._pending: list[tuple[RoundRead, bool, Future[Reconciliation]]] = []
        self._changed = threading.Condition()
        self._stopped = False
        self._thread: threading.Thread | None = None
        #: how many rounds each batch stored, the last ones
        self.sizes: deque[int] = deque(maxlen=64)

    def store(self, read: RoundRead, final: bool) -> Reconciliation:
        """Store this read with the others pending; its answer (or what storing it raised)."""
        done: Future[Reconciliation] = Future()
        with self._changed:
            if self._stopped:
                raise RuntimeError("the watcher stopped")
            self._pending.append((read, final, done))
            if self._thread is None:
                self._thread = threading.Thread(
                    target=self._run, name="tcpcal-watcher-store", daemon=True
                )
                self._thread.start()
            self._changed.notify_all()
        return done.result()

    def stop(self) -> None:
        """Store what is pending, then end."""
        with self._changed:
            self._stopped = True
            self._changed.notify_all()

    def join(self, until: float) -> None:
        thread = self._thread
        if thread is not None:
            thread.join(max(0.0, until - time.monotonic()))

    def _run(self) -> None:
        batch: list[tuple[RoundRead, bool, Future[Reconciliation]]] = []
        try:
            while True:
                with self._changed:
                    self._changed.wait_for(lambda: self._pending or self._stopped)
                    batch = self._pending[:STORE_BATCH]
                    self._pending = self._pending[STORE_BATCH:]
                    if not batch and self._stopped:
                        return
                self._store(batch)
        except BaseException as exc:  # no reader waits for ever on a store thread gone
            log.exception("the watcher's store failed")
            with self._changed:
                failed, self._pending = [*batch, *self._pending], []
                self._thread = None  # the next store starts another
            for _, _, done in failed:
                if not done.done():
                    done.set_exception(exc)

    def _store(self, batch: list[tuple[RoundRead, bool, Future[Reconciliation]]]) -> None:
        self.sizes.append(len(batch))
        try:
            stored = store_rounds(
                [read for read, _, _ in batch],
                self._actor,
                self._trigger,
                final=[final for _, final, _ in batch],
            )
        except BaseException as exc:  # the database down: every reader hears it
            for _, _, done in batch:
                done.set_exception(exc)
            return
        for (_, _, done), one in zip(batch, stored, strict=True):
            try:
                done.set_result(one.result())
            except BaseException as exc:  # that robot's own error, raised in its reader
                done.set_exception(exc)


@dataclass(frozen=True)
class Overrun:
    """A round that did not begin reading every robot within its interval, and what would
    have fitted it: the interval its reads took at the pool's size, and the size at which
    they would have fitted this interval."""

    robots: int
    unread: int
    interval_s: float
    median_read_s: float
    concurrency: int
    interval_needed_s: float
    concurrency_needed: int
    #: the instances sharing the fleet (PostgreSQL's leases): `robots` and `unread` are the
    #: fleet's, `concurrency` and `concurrency_needed` each instance's
    watchers: int = 1

    def words(self) -> str:
        where = "" if self.watchers == 1 else f" on each of {self.watchers} instances"
        said = (
            f"{self.unread} of {self.robots} robots not yet read when the {self.interval_s} s "
            f"interval ended (reads take {self.median_read_s:.3f} s, {self.concurrency} at "
            f"once{where})"
        )
        if self.interval_needed_s <= self.interval_s:
            return (
                f"{said}: reads of that length fit the interval at that concurrency, so the "
                "robots unread waited on reads that stalled (reads_stalled in /ready) or on "
                "the leases of an instance that stopped; a longer interval would not help"
            )
        return (
            f"{said}: set TCPCAL_RECONCILE_INTERVAL_S to at least {self.interval_needed_s} or "
            f"TCPCAL_RECONCILE_CONCURRENCY to at least {self.concurrency_needed}"
        )


@dataclass
class WatcherStatus:
    """What /ready says of this process's watcher."""

    interval_s: float
    concurrency: int
    #: each robot is read this often (period_after), the interval until reads are measured
    period_s: float = 0.0
    running: bool = False
    rounds: int = 0
    rounds_skipped: int = 0
    robots: int = 0
    last_round_at: datetime | None = None
    last_round_s: float | None = None
    last_error: str | None = None
    overruns: int = 0
    last_overrun: Overrun | None = None
    errors: dict[str, str] = field(default_factory=dict)

    def document(self) -> dict[str, object]:
        overrun = self.last_overrun
        return {
            "enabled": True,
            "interval_s": self.interval_s,
            "period_s": self.period_s,
            "concurrency": self.concurrency,
            "running": self.running,
            "pid": os.getpid(),
            "robots": self.robots,
            "rounds": self.rounds,
            "rounds_skipped_locked": self.rounds_skipped,
            "rounds_overrun": self.overruns,
            "last_overrun": None if overrun is None else overrun.words(),
            "last_round_at": None if self.last_round_at is None else self.last_round_at.isoformat(),
            "last_round_s": self.last_round_s,
            "last_error": self.last_error,
        }


def pool_size(robots: int, read_s: float, interval_s: float, least: int) -> int:
    """Threads reading at once for `robots` reads of `read_s` each to end within half the
    interval (the other half for reads that take longer), at least `least` (the setting),
    else at most MAX_SIZE, and no more than the robots."""
    needed = math.ceil(robots * read_s / max(interval_s / 2, 1e-3))
    return max(1, min(max(least, min(needed, MAX_SIZE)), max(robots, least)))


def period_after(interval_s: float, settle_s: float | None, tick_s: float = 0.0) -> float:
    """How often a robot is read for a change at its controller to be recorded within the
    interval: the interval less the lead, the longest offer-to-stored time of the last reads
    (FIRST_READ_S before any) and the tick that offers a robot due (PostgreSQL's), at most
    LEAD_SHARE of the interval."""
    lead = tick_s + (FIRST_READ_S if settle_s is None else settle_s)
    return interval_s - min(lead, LEAD_SHARE * interval_s)


def stall_after(read_s: float, interval_s: float) -> float:
    """When a read has stalled: 4 times the median read, 0.25 s to half the interval."""
    return max(0.25, min(4 * read_s, interval_s / 2))


class Watcher:
    """Reconciles every robot with a controller every `interval_s`, in a daemon thread, at
    least `concurrency` controllers at once (default TCPCAL_RECONCILE_CONCURRENCY) and as
    many more as the fleet's reads need to end within half the interval."""

    def __init__(self, interval_s: float, concurrency: int | None = None) -> None:
        least = get_settings().reconcile_concurrency if concurrency is None else concurrency
        self.least = least
        self.status = WatcherStatus(
            interval_s=interval_s, concurrency=least, period_s=period_after(interval_s, None)
        )
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._pool = ReadPool(least, self._reconcile)
        self._stores = StoreBatches(WATCHER, "watcher")
        #: The fleet lock while this watcher holds it (across rounds while reads are in flight)
        self._lock: ExitStack | None = None
        #: Robots whose protocol this tcpcal has no connector for, warned of once each
        self._no_connector: set[str] = set()
        #: This instance's name in the leases (PostgreSQL), once its loop began
        self.holder: str | None = None
        #: Robots whose last read stalled: offered after the others
        self._slow: set[str] = set()

    def document(self) -> dict[str, object]:
        """The watcher's state for /ready, with the reads now in flight."""
        return self.status.document() | {
            "reads_in_flight": self._pool.in_flight(),
            "reads_stalled": self._pool.stalled(),
        }

    def start(self) -> None:
        """Start the loop (its first round at once)."""
        self._stop.clear()
        self._pool = ReadPool(self.least, self._reconcile)
        self._stores = StoreBatches(WATCHER, "watcher")
        self._thread = threading.Thread(target=self._loop, name="tcpcal-watcher", daemon=True)
        self._thread.start()
        self.status.running = True

    def stop(self, timeout_s: float = 0.9) -> None:
        """Ask the loop and its reads to end and wait up to `timeout_s` for them: a read that
        has ended stores nothing after this, and one storing what it found finishes first (the
        database may be closed next). A read stalled on a controller ends on its own at that
        controller's timeout, storing nothing; the threads are daemons."""
        until = time.monotonic() + timeout_s
        self._stop.set()
        self._pool.stop()
        if self._thread is not None:
            self._thread.join(timeout_s)
        self._pool.join(until)
        self._stores.stop()  # after the reads: the ones storing what they found finish first
        self._stores.join(until)
        if self._thread is None or not self._thread.is_alive():
            self._release()  # rounds run without the loop keep the lock while reads are in flight
        self.status.running = False
        WATCHED_ROBOTS.set(0)

    def _loop(self) -> None:
        if not is_sqlite(get_engine()):
            self._lease_loop()
            return
        try:
            while not self._stop.is_set():
                started = time.monotonic()
                try:
                    self.round()
                except Exception as exc:  # a database outage must not end the loop
                    self.status.last_error = f"{type(exc).__name__}: {exc}"
                    log.exception("watcher round failed")
                self._stop.wait(max(0.0, self._period() - (time.monotonic() - started)))
        finally:
            self._release()

    def _lease_loop(self) -> None:
        """PostgreSQL: every tick, claim this instance's share of the due robots (leases,
        app.services.controllers.leases) and read them; a round is each interval."""
        leases = Leases(self.status.interval_s)
        self.holder = leases.holder
        claims: deque[tuple[float, list[str]]] = deque()
        round_began = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            try:
                capacity = self._capacity(leases.tick_s)
                period = self._period(leases.tick_s)
                tick = leases.tick(self._pool.in_flight_ids(), capacity, now, period_s=period)
                self._pool.offer(tick.claimed)
                claims.append((now, tick.claimed))
                if now - round_began >= self.status.interval_s or self.status.rounds == 0:
                    self._lease_round(claims, tick, now - round_began, leases.tick_s)
                    round_began = now
            except Exception as exc:  # a database outage must not end the loop
                self.status.last_error = f"{type(exc).__name__}: {exc}"
                log.exception("watcher tick failed")
            self._pool.serve_for(leases.tick_s)
        with suppress(Exception):  # the database may be gone: the leases lapse on their own
            leases.leave()

    def _capacity(self, tick_s: float) -> int:
        """How many robots a tick claims at most: what the pool begins before the next tick
        (its size, and as many more as its reads end within a tick), less its reads in flight
        that hold a place (a stalled read holds none: ten hung controllers claimed nothing
        else for their timeout).
        Claimed twice the pool ahead, a robot waited a read for its place (1.3 s under load),
        and the period left that wait as lead: 2000 robots read every 7.1 s, not 9.5."""
        size = self._pool.size
        read_s = self._pool.median_read_s() or FIRST_READ_S
        ahead = math.ceil(size * min(1.0, tick_s / max(read_s, 1e-3)))
        return max(0, size + ahead - (self._pool.in_flight() - self._pool.stalled()))

    def _lease_round(
        self, claims: deque[tuple[float, list[str]]], tick: Tick, took_s: float, tick_s: float
    ) -> None:
        """A round's end on PostgreSQL: the robots this instance claimed in the last period
        are the ones it watches; the pool is sized for its share of the fleet. An overrun is
        said of the fleet (its robots, the ones overdue, every instance's pool), as the
        leases count it."""
        share = math.ceil(tick.robots / max(1, tick.watchers))
        # the robots read in the last period (a claim waits for a tick): one a robot in a
        # period, whichever instance read it the period before
        since = time.monotonic() - self.status.period_s - tick_s
        while claims and claims[0][0] < since:
            claims.popleft()
        self._size(max(share, 1))
        watched = len({robot_id for _, claimed in claims for robot_id in claimed})
        self.status.robots = watched
        WATCHED_ROBOTS.set(watched)
        if tick.overdue > 0 and self.status.rounds > 0 and tick.reports:
            # one instance says the fleet's overrun (counted, logged), not every one of them
            self._overrun(tick.robots, tick.overdue, watchers=max(1, tick.watchers))
        self._finish_round(took_s)

    def round(self) -> None:
        """One round, if this instance holds the lock: every robot with a controller whose
        last read has ended is read again, offered evenly over SPREAD of the period; the round
        waits up to its period for them."""
        if not self._take_lock():
            self.status.rounds_skipped += 1
            return
        try:
            started = time.monotonic()
            robots = robots_with_controller()
            self._size(len(robots))
            # robots whose last read stalled go last: a hung controller first in line would
            # hold a place for stall_s before the healthy ones behind it are read
            ordered = sorted(robots, key=lambda robot_id: robot_id in self._slow)
            period = self._period()
            offered = self._offer_paced(ordered, started, SPREAD * period)
            done = self._pool.wait(offered, max(0.0, started + period - time.monotonic()))
            if self._stop.is_set():
                return
            if not done:
                self._overrun(len(robots), self._pool.queued(offered))
            self._finish_round(time.monotonic() - started)
        finally:
            if self._pool.in_flight() == 0:  # else held into the next round
                self._release()

    def _offer_paced(self, robots: list[str], started: float, spread_s: float) -> set[str]:
        """Offer the k-th of `robots` at `started` + k x `spread_s` / len(robots) (those due
        within PACE_S together); the ones queued."""
        offered: set[str] = set()
        slot = spread_s / max(1, len(robots))
        k = 0
        while k < len(robots) and not self._stop.is_set():
            ahead = started + k * slot - time.monotonic()
            if ahead > PACE_S:
                self._pool.serve_for(ahead)
                continue
            together = len(robots) if slot <= 0 else 1 + int((PACE_S - ahead) / slot)
            upto = min(len(robots), k + together)
            offered |= self._pool.offer(robots[k:upto])
            k = upto
        return offered

    def _period(self, tick_s: float = 0.0) -> float:
        """Each robot's period now (period_after), said in /ready."""
        period = period_after(self.status.interval_s, self._pool.longest_settle_s(), tick_s)
        self.status.period_s = round(period, 3)
        return period

    def _size(self, robots: int) -> None:
        """Size the pool and its stall time from the fleet, the interval and the reads."""
        read_s = self._pool.median_read_s() or FIRST_READ_S
        self._pool.stall_s = stall_after(read_s, self.status.interval_s)
        self._pool.resize(pool_size(robots, read_s, self.status.interval_s, self.least))
        self.status.concurrency = self._pool.size
        self.status.robots = robots
        WATCHED_ROBOTS.set(robots)
        WATCHER_CONCURRENCY.set(self._pool.size)

    def _finish_round(self, took_s: float) -> None:
        self.status.rounds += 1
        self.status.last_round_at = utcnow()
        self.status.last_round_s = round(took_s, 3)
        WATCHER_ROUND_SECONDS.set(took_s)

    def _overrun(self, robots: int, unread: int, *, watchers: int = 1) -> None:
        """The round's interval ended before every robot's read began: say so, with the
        interval and the pool size that would have fitted it. `robots` and `unread` are
        counted over the `watchers` instances that share them, each with a pool this size."""
        if unread == 0:
            return  # only reads that began and have not ended (a hung controller's)
        interval = self.status.interval_s
        read_s = self._pool.median_read_s() or FIRST_READ_S
        size = self._pool.size
        overrun = Overrun(
            robots=robots,
            unread=unread,
            interval_s=interval,
            median_read_s=read_s,
            concurrency=size,
            interval_needed_s=math.ceil(10 * 2 * robots * read_s / (size * watchers)) / 10,
            concurrency_needed=math.ceil(robots * read_s / max(interval / 2, 1e-3) / watchers),
            watchers=watchers,
        )
        self.status.overruns += 1
        self.status.last_overrun = overrun
        WATCHER_OVERRUNS.inc()
        WATCHER_INTERVAL_NEEDED.set(overrun.interval_needed_s)
        events.warning(
            "watcher.round_overrun",
            robots=robots,
            unread=unread,
            interval_s=interval,
            median_read_s=round(read_s, 4),
            concurrency=size,
            watchers=watchers,
            interval_needed_s=overrun.interval_needed_s,
            concurrency_needed=overrun.concurrency_needed,
            detail=overrun.words(),
        )

    def _take_lock(self) -> bool:
        if self._lock is not None:
            return True
        stack = ExitStack()
        if not stack.enter_context(fleet_lock()):
            stack.close()
            return False
        self._lock = stack
        return True

    def _release(self) -> None:
        stack, self._lock = self._lock, None
        if stack is not None:
            stack.close()

    def _reconcile(self, robot_id: str) -> None:
        """One robot, in a pool thread: its states are stored as its read ends."""
        if self._stop.is_set():
            return
        began = time.monotonic()
        try:
            self._reconcile_one(robot_id)
        finally:
            if time.monotonic() - began >= self._pool.stall_s:
                self._slow.add(robot_id)
            else:
                self._slow.discard(robot_id)

    def _reconcile_one(self, robot_id: str) -> None:
        try:
            reconcile_robot(
                robot_id=robot_id,
                actor=WATCHER,
                trigger="watcher",
                cancelled=self._stop.is_set,
                store=self._stores.store,
            )
        except ConnectorMissing as exc:  # stored for a later tcpcal: not a fault of this one
            self.status.last_error = f"robot {robot_id}: {exc}"
            if robot_id not in self._no_connector:
                self._no_connector.add(robot_id)
                events.warning("watcher.no_connector", robot_id=robot_id, detail=str(exc))
            return
        except Exception as exc:  # one robot's failure must not stop the others
            self.status.last_error = f"robot {robot_id}: {type(exc).__name__}: {exc}"
            log.exception("watcher could not reconcile robot %s", robot_id)


#: This process's watcher, when one runs (for /ready).
CURRENT: Watcher | None = None


def watcher_document() -> dict[str, object]:
    """The watcher's state for /ready: {"enabled": false} when none runs."""
    if CURRENT is None:
        return {"enabled": False}
    return CURRENT.document()


def start_watcher(interval_s: float) -> Watcher:
    """Start this process's watcher."""
    global CURRENT
    watcher = Watcher(interval_s)
    watcher.start()
    CURRENT = watcher
    return watcher


def stop_watcher() -> None:
    """Stop this process's watcher, within a second."""
    global CURRENT
    if CURRENT is not None:
        CURRENT.stop()
        CURRENT = None
