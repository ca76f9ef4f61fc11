"""Leases: several instances on PostgreSQL share the watcher's rounds, each robot read by
exactly one of them a round, with no fleet lock (issue 50: one advisory lock let one
instance watch the fleet however many served it).

Each robot with a controller has a row of `watch_leases`: when it is next due (`due_at`)
and who reads it until when (`holder`, `leased_until`). Every tick an instance says it is
alive (`watchers`), renews the leases of its reads in flight, lets go of the others, and
claims robots that are due and held by no live lease, `FOR UPDATE SKIP LOCKED`, at most its
share (the due robots over the instances seen within a lease) and what its pool can start;
a claim moves `due_at` one period on (the interval less the lead a read needs to be stored,
app.services.controllers.watcher.period_after; half an interval from now at least, for a
robot overdue), so a robot is claimed once a period. An instance killed mid-round renews nothing:
its reads' leases lapse within `lease_s`, it takes no share of the others' claims after that,
and its claimed robots are due again one period after their claim, when another instance
claims them. The first live instance by name says what is said once for the fleet (its
round's overrun). Times are the database's (`now()`), so the instances' clocks need not
agree. A tick is two statements (two more once an interval: robots given a controller since, and
instances gone long enough to be forgotten).
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

_ROWS = text(
    "INSERT INTO watch_leases (robot_id, due_at) "
    "SELECT rc.robot_id, now() FROM robot_controllers rc "
    "JOIN robots r ON r.id = rc.robot_id WHERE r.archived_at IS NULL "
    "ON CONFLICT (robot_id) DO NOTHING"
)
#: Instances not seen for `:gone` seconds are forgotten (an instance killed, or stopped without
#: leave(), stayed listed for ever): counted by no tick since a lease after it was last seen,
#: so no count of /ready or /metrics changes; one that comes back is listed again by its next
#: tick.
_GONE = text("DELETE FROM watchers WHERE seen_at < now() - make_interval(secs => :gone)")
#: This instance is alive, and its leases are renewed (its reads in flight) or let go: one
#: statement (the INSERT a data-modifying WITH, run whether or not the UPDATE reads it).
_ALIVE = text(
    "WITH seen AS (INSERT INTO watchers (holder, seen_at) VALUES (:me, now()) "
    "ON CONFLICT (holder) DO UPDATE SET seen_at = now() RETURNING holder) "
    "UPDATE watch_leases SET leased_until = CASE WHEN robot_id = ANY(:reading) "
    "THEN now() + make_interval(secs => :lease) ELSE NULL END "
    "WHERE holder = :me AND leased_until IS NOT NULL"
).bindparams(bindparam("reading", type_=ARRAY(String)))
_FLEET = (
    "FROM watch_leases l JOIN robot_controllers rc ON rc.robot_id = l.robot_id "
    "JOIN robots r ON r.id = l.robot_id WHERE r.archived_at IS NULL"
)
_FREE = "(l.leased_until IS NULL OR l.leased_until < now())"
#: What the tick sees and what it claims, in one statement: the live instances (seen within a
#: lease: one whose leases would have lapsed is gone) and the first of them by name, the
#: fleet's robots, the ones due and the ones overdue by an interval, and the claim of this
#: instance's share of the due ones (at most :cap) with the count it was made from (the
#: WITH queries share one snapshot: the claim is counted before it).
_CLAIM = text(
    "WITH live AS (SELECT count(*) AS n, min(holder) AS first FROM watchers "
    "WHERE seen_at > now() - make_interval(secs => :lease)), "
    "fleet AS (SELECT count(*) AS robots, "
    f"count(*) FILTER (WHERE l.due_at <= now() AND {_FREE}) AS due, "
    f"count(*) FILTER (WHERE l.due_at < now() - make_interval(secs => :i) AND {_FREE}) "
    f"AS overdue {_FLEET}), "
    "claimed AS (UPDATE watch_leases SET holder = :me, "
    "leased_until = now() + make_interval(secs => :lease), "
    "due_at = GREATEST(due_at + make_interval(secs => :p), now() + make_interval(secs => :h)) "
    f"WHERE robot_id IN (SELECT l.robot_id {_FLEET} AND l.due_at <= now() AND {_FREE} "
    "ORDER BY l.due_at LIMIT (SELECT LEAST(:cap, CEIL(fleet.due / GREATEST(1, live.n)::numeric)) "
    "FROM fleet, live)::bigint FOR UPDATE OF l SKIP LOCKED) RETURNING robot_id) "
    "SELECT live.n, live.first, fleet.robots, fleet.due, fleet.overdue, "
    "ARRAY(SELECT robot_id FROM claimed) AS claimed FROM live, fleet"
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
    #: this instance is the first live one by name: it says what is said once for the
    #: fleet (an overrun of the fleet's round counted and logged by one instance, not each)
    reports: bool = True


class Leases:
    """One instance's side of the leases."""

    def __init__(self, interval_s: float, *, holder: str | None = None) -> None:
        self.holder = holder or holder_name()
        self.interval_s = interval_s
        #: how often the watcher ticks (claims, renews): a fortieth of the interval, 0.02-0.25 s.
        #: A robot due waits for the next tick, and a tick claims what the pool begins before
        #: the next (Watcher._capacity): at a tenth of a 10 s interval, claiming twice the
        #: pool a tick, 3 instances read 2000 robots 0.82 times an interval.
        self.tick_s = min(0.25, max(0.02, interval_s / 40))
        #: a lease not renewed for this long lapses, and an instance not seen for this long
        #: is gone (one that died: it takes no share of a claim after)
        self.lease_s = max(3 * self.tick_s, 1.0)
        #: an instance not seen for this long is no longer listed in `watchers`
        self.forget_s = max(10 * self.lease_s, interval_s)
        self._rows_at = -math.inf

    def tick(
        self, reading: set[str], capacity: int, now: float, *, period_s: float | None = None
    ) -> Tick:
        """Say this instance is alive, renew the leases of `reading` (let go of the rest),
        and claim up to this instance's share of the due robots, at most `capacity`, each
        due again `period_s` on (default: the interval): two
        statements (two more once an interval: robots given a controller since, and instances not
        seen for `forget_s` forgotten)."""
        with session_scope(write=True) as session:
            if now - self._rows_at >= self.interval_s:
                session.execute(_ROWS)
                session.execute(_GONE, {"gone": self.forget_s})
                self._rows_at = now
            session.execute(
                _ALIVE, {"me": self.holder, "reading": sorted(reading), "lease": self.lease_s}
            )
            params = {
                "me": self.holder,
                "lease": self.lease_s,
                "i": self.interval_s,
                "p": self.interval_s if period_s is None else period_s,
                "h": self.interval_s / 2,
                "cap": max(0, capacity),
            }
            watchers, first, robots, due, overdue, claimed = session.execute(_CLAIM, params).one()
        return Tick(
            list(claimed),
            int(robots),
            int(due),
            int(overdue),
            int(watchers),
            reports=first == self.holder,
        )

    def leave(self) -> None:
        """Let go of every lease and say this instance is gone (a clean stop)."""
        with session_scope(write=True) as session:
            session.execute(
                text("UPDATE watch_leases SET leased_until = NULL WHERE holder = :me"),
                {"me": self.holder},
            )
            session.execute(text("DELETE FROM watchers WHERE holder = :me"), {"me": self.holder})
