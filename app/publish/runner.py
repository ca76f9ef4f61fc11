"""The publisher's loop: drain the outbox in order into every sink, mark, prune.

`tcpcal publish` (app.cli) builds the sinks from the configuration (app.publish.sinks: MQTT
when TCPCAL_MQTT_URL is set, OPC UA when TCPCAL_OPCUA_ENDPOINT is), then `Runner.run`:

1. takes the fleet lock (app.publish.lock): a second publisher waits here;
2. opens every sink (a wrong configuration raises SinkError: the command prints it and
   exits non-zero);
3. loops until SIGTERM: for a sink whose `connection_id()` changed, the state of every live
   tool first; then up to `batch` undelivered rows in id order with the current state of the
   tools they concern; every sink must accept the batch (`deliver` returns True, MQTT: every
   PUBACK) before its rows are marked delivered, in one transaction after the sends. A
   failed batch is sent again (with freshly read states) once the sink is back: at least
   once, never out of order for a tool. A kill -9 between the sends and the mark leaves the
   rows undelivered, and the next publisher sends them again. Delivered rows are pruned
   `keep_s` after delivery.

Stops within a second of SIGTERM or SIGINT (every wait checks `stopping`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence

from sqlalchemy import Engine
from sqlalchemy.exc import SQLAlchemyError

from app.publish import source
from app.publish.lock import FleetLock, fleet_lock
from app.publish.sink import Batch, Sink, SinkError
from app.storage.db import session_scope

log = logging.getLogger(__name__)

#: What one pass of the loop did.
DELIVERED, IDLE, FAILED = "delivered", "idle", "failed"
#: Seconds between attempts while a sink (or the database) is away.
RETRY_S = 0.5


class LockLost(SinkError):
    """The connection that held the fleet lock is gone (the database restarted)."""


class Runner:
    """Drains the outbox of `engine` into `sinks` until `stopping` is set."""

    def __init__(
        self,
        engine: Engine,
        sinks: Sequence[Sink],
        stopping: threading.Event,
        *,
        batch: int = 200,
        poll_s: float = 0.2,
        keep_s: float = 300.0,
    ) -> None:
        self.engine = engine
        self.sinks = list(sinks)
        self.stopping = stopping
        self.batch = batch
        self.poll_s = poll_s
        self.keep_s = keep_s
        self._full_sent: dict[str, int] = {}
        self.delivered = 0  # rows delivered since start (logs, tests)

    def run(self) -> None:
        """Take the fleet lock, open the sinks and publish until stopped."""
        with fleet_lock(self.engine, self.stopping) as lock:
            if lock is None:
                return
            opened: list[Sink] = []
            try:
                for sink in self.sinks:
                    sink.open(self.stopping)
                    opened.append(sink)
                if self.stopping.is_set():  # told to stop while a sink was connecting
                    return
                log.info("publishing to %s", ", ".join(s.name for s in self.sinks))
                self._loop(lock)
            finally:
                for sink in reversed(opened):
                    sink.close()

    def _loop(self, lock: FleetLock) -> None:
        checked = time.monotonic()
        while not self.stopping.is_set():
            if time.monotonic() - checked > 2.0:
                if not lock.held():
                    raise LockLost("lost the database connection that held the fleet lock")
                checked = time.monotonic()
            try:
                outcome = self.step()
            except SQLAlchemyError as exc:
                log.warning("database error, retrying: %s", exc)
                outcome = FAILED
            if outcome == IDLE:
                self.stopping.wait(self.poll_s)
            elif outcome == FAILED:  # a sink or the database is away: no busy loop meanwhile
                self.stopping.wait(RETRY_S)

    def step(self) -> str:
        """One pass: full states owed, then one batch of the outbox. DELIVERED (the next
        pass follows at once), IDLE (nothing to send) or FAILED (a sink did not take it)."""
        for sink in self.sinks:
            if not self._full_state(sink):
                return FAILED
        with session_scope(write=False, engine=self.engine) as session:
            source.snapshot(session)
            messages = source.undelivered(session, limit=self.batch)
            if not messages:
                return IDLE
            states = source.states(session, source.subjects_concerned(session, messages))
        batch = Batch(messages=messages, states=states)
        accepted = [sink.deliver(batch) for sink in self.sinks]  # each sink, even after one fails
        if not all(accepted):
            return FAILED
        with session_scope(write=True, engine=self.engine) as session:
            source.mark_delivered(session, [m.id for m in messages])
            source.prune(session, keep_seconds=self.keep_s)
        self.delivered += len(messages)
        return DELIVERED

    def _full_state(self, sink: Sink) -> bool:
        """Send every live subject's state to a sink that (re)connected; True when it has it."""
        connection = sink.connection_id()
        if self._full_sent.get(sink.name) == connection:
            return True
        for page in source.live_pages(self.engine, page=self.batch):
            with session_scope(write=False, engine=self.engine) as session:
                source.snapshot(session)
                states = source.states(session, page)
            if self.stopping.is_set() or not sink.deliver(Batch(states=states, full=True)):
                return False
        self._full_sent[sink.name] = connection
        log.info("full state sent to %s", sink.name)
        return True
