"""Leases: several instances on PostgreSQL share the watcher's rounds, each robot read by
exactly one of them a round, with no fleet lock (issue 50: one advisory lock let one
instance watch the fleet however many served it).

Each robot with a controller has a row of `watch_leases`: when it is next due (`due_at`)
and who reads it until when (`holder`, `leased_until`). Every tick an instance says it is
alive (`watchers`), renews the leases of its reads in flight, lets go of the others, and
claims robots that are due and held by no live lease, `FOR UPDATE SKIP LOCKED`, at most its
share (the due robots over the instances seen) and what its pool can start; a claim moves
`due_at` one interval on (half an interval from now at least, for a robot overdue), so a
robot is claimed once a round. An instance killed mid-round
renews nothing: its reads' leases lapse within `lease_s` and its claimed robots are due
again one interval after their claim, when another instance claims them. Times are the
database's (`now()`), so the instances' clocks need not agree.
"""

from __future__ import annotations

import math
import os
import socket
import uuid
from dataclasses import dataclass

from sqlalchemy import bindparam, text
from sqlalchemy.dialects.postgresql import ARRAY
from sqlalchemy.types import String

from app.storage.db import session_scope

_SEEN = text(
    "INSERT INTO watchers (holder, seen_at) VALUES (:me, now()) "
    "ON CONFLICT (holder) DO UPDATE SET seen_at = now()"
)
_LIVE = text("SELECT count(*) FROM watchers WHERE seen_at > now() - make_interval(secs => :s)")
_ROWS = text(
    "INSERT INTO watch_leases (robot_id, due_at) "
    "SELECT rc.robot_id, now() FROM robot_controllers rc "
    "JOIN robots r ON r.id = rc.robot_id WHERE r.archived_at IS NULL "
    "ON CONFLICT (robot_id) DO NOTHING"
)
_RENEW = text(
    "UPDATE watch_leases SET leased_until = CASE WHEN robot_id = ANY(:reading) "
    "THEN now() + make_interval(secs => :lease) ELSE NULL END "
    "WHERE holder = :me AND leased_until IS NOT NULL"
).bindparams(bindparam("reading", type_=ARRAY(String)))
_DUE = (
    "FROM watch_leases l JOIN robot_controllers rc ON rc.robot_id = l.robot_id "
    "JOIN robots r ON r.id = l.robot_id WHERE r.archived_at IS NULL AND l.due_at <= now() "
    "AND (l.leased_until IS NULL OR l.leased_until < now())"
)
_FREE = "(l.leased_until IS NULL OR l.leased_until < now())"
_COUNT = text(
    "SELECT count(*), count(*) FILTER (WHERE l.due_at <= now() AND " + _FREE + "), "
    "count(*) FILTER (WHERE l.due_at < now() - make_interval(secs => :i) AND " + _FREE + ") "
    "FROM watch_leases l JOIN robot_controllers rc ON rc.robot_id = l.robot_id "
    "JOIN robots r ON r.id = l.robot_id WHERE r.archived_at IS NULL"
)
_CLAIM = text(
    "UPDATE watch_leases SET holder = :me, leased_until = now() + make_interval(secs => :lease), "
    "due_at = GREATEST(due_at + make_interval(secs => :i), now() + make_interval(secs => :h)) "
    "WHERE robot_id IN ("
    f"SELECT l.robot_id {_DUE} ORDER BY l.due_at LIMIT :n FOR UPDATE OF l SKIP LOCKED) "
    "RETURNING robot_id"
)


def holder_name() -> str:
    """This instance's name in the leases: host, process and a random part."""
    return f"{socket.gethostname()[:60]}:{os.getpid()}:{uuid.uuid4().hex[:8]}"


@dataclass(frozen=True)
class Tick:
    """What one tick claimed, and what it saw of the fleet."""

    claimed: list[str]
    robots: int
    due: int
    overdue: int
    watchers: int


class Leases:
    """One instance's side of the leases."""

    def __init__(self, interval_s: float, *, holder: str | None = None) -> None:
        self.holder = holder or holder_name()
        self.interval_s = interval_s
        #: how often the watcher ticks (claims, renews): a tenth of the interval, 0.02-1 s
        self.tick_s = min(1.0, max(0.02, interval_s / 10))
        #: a lease not renewed for this long lapses (an instance that died)
        self.lease_s = max(3 * self.tick_s, 1.0)
        self._rows_at = -math.inf

    def tick(self, reading: set[str], capacity: int, now: float) -> Tick:
        """Say this instance is alive, renew the leases of `reading` (let go of the rest),
        and claim up to this instance's share of the due robots, at most `capacity`."""
        with session_scope(write=True) as session:
            session.execute(_SEEN, {"me": self.holder})
            if now - self._rows_at >= self.interval_s:  # robots given a controller since
                session.execute(_ROWS)
                self._rows_at = now
            session.execute(
                _RENEW, {"me": self.holder, "reading": sorted(reading), "lease": self.lease_s}
            )
            watchers = int(session.execute(_LIVE, {"s": 3 * self.lease_s}).scalar_one())
            robots, due, overdue = session.execute(_COUNT, {"i": self.interval_s}).one()
            share = min(capacity, math.ceil(int(due) / max(1, watchers)))
            claimed: list[str] = []
            if share > 0:
                params = {
                    "me": self.holder,
                    "lease": self.lease_s,
                    "i": self.interval_s,
                    "h": self.interval_s / 2,
                }
                claimed = list(session.scalars(_CLAIM, params | {"n": share}))
        return Tick(claimed, int(robots), int(due), int(overdue), watchers)

    def leave(self) -> None:
        """Let go of every lease and say this instance is gone (a clean stop)."""
        with session_scope(write=True) as session:
            session.execute(
                text("UPDATE watch_leases SET leased_until = NULL WHERE holder = :me"),
                {"me": self.holder},
            )
            session.execute(text("DELETE FROM watchers WHERE holder = :me"), {"me": self.holder})
