"""Issue 50, PostgreSQL's leases (app.services.controllers.leases): each instance claims its
share of the robots due among the instances alive, an instance whose leases would have
lapsed takes no share, one instance says what is said once for the fleet, and every robot
due is claimed by exactly one instance."""

from __future__ import annotations

import time

import pytest
from sqlalchemy import text

from app.services.controllers.leases import Leases
from app.storage.db import get_engine
from tests.conftest import Api, Database

INTERVAL_S = 0.2  # ticks of 0.02 s; a lease of 1 s


def _fleet(api: Api, db: Database, n: int) -> list[str]:
    if db.backend == "sqlite":
        pytest.skip("SQLite keeps one watcher (its flock): no leases")
    ids = []
    for i in range(n):
        robot = api.robot(f"leased{i}")
        body = {"protocol": "kuka_kvp", "host": "127.0.0.1", "port": 7000 + i}
        put = api.request("PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=body)
        assert put.status_code == 200, put.text
        ids.append(robot["id"])
    return sorted(ids)


def _all_due() -> None:
    with get_engine().begin() as conn:
        conn.execute(text("UPDATE watch_leases SET due_at = now() - interval '1 second'"))


def test_an_instance_gone_a_lease_takes_no_share_of_the_claims(api: Api, db: Database) -> None:
    """Two instances alive share the robots due; once one has not ticked for a lease (1 s:
    killed), the other claims every robot due, not half (it counted the instances seen
    within 3 leases, and for 3 s claimed half the fleet's due robots a tick)."""
    robots = _fleet(api, db, 6)
    alive, killed = Leases(INTERVAL_S, holder="a-alive"), Leases(INTERVAL_S, holder="b-killed")
    now = time.monotonic()
    assert killed.tick(set(), 0, now).claimed == []  # seen, claims nothing
    first = alive.tick(set(), 100, now)
    assert (first.robots, first.due, first.watchers) == (6, 6, 2)
    assert len(first.claimed) == 3  # its share: 6 due over 2 instances
    alive.tick(set(), 0, now)  # lets go of the three it did not read

    time.sleep(alive.lease_s + 0.2)  # the killed instance not seen for a lease
    _all_due()
    after = alive.tick(set(), 100, time.monotonic())
    assert after.watchers == 1
    assert sorted(after.claimed) == robots


def test_one_instance_reports_for_the_fleet_the_first_alive_by_name(api: Api, db: Database) -> None:
    """The first live instance by name says what is said once for the fleet (an overrun is
    counted and logged by it, not by every instance); when it stops, the next one does."""
    _fleet(api, db, 2)
    first, second = Leases(INTERVAL_S, holder="a-first"), Leases(INTERVAL_S, holder="b-second")
    now = time.monotonic()
    assert first.tick(set(), 0, now).reports
    assert not second.tick(set(), 0, now).reports
    assert first.tick(set(), 0, now).reports
    first.leave()  # a clean stop: gone at once
    assert second.tick(set(), 0, now).reports


def test_every_robot_due_is_claimed_once_by_one_instance(api: Api, db: Database) -> None:
    """Three instances claiming in turn take disjoint shares of the robots due, together all
    of them within two ticks, each robot's due time moved on so that none is claimed again
    this round; the counts they see are the fleet's, taken before their own claim."""
    robots = _fleet(api, db, 7)
    instances = [Leases(INTERVAL_S, holder=f"i{n}") for n in range(3)]
    now = time.monotonic()
    for leases in instances:
        leases.tick(set(), 0, now)  # all three seen
    _all_due()
    ticks = [leases.tick(set(), 100, now) for leases in instances]
    # each its share of what is due when it ticks: ceil(7/3), ceil(4/3), ceil(2/3)
    assert [len(tick.claimed) for tick in ticks] == [3, 2, 1]
    assert [tick.due for tick in ticks] == [7, 4, 2]
    assert all(tick.robots == 7 and tick.watchers == 3 for tick in ticks)
    ticks += [leases.tick(set(), 100, now) for leases in instances]  # the next tick: the rest
    assert [len(tick.claimed) for tick in ticks[3:]] == [1, 0, 0]
    claimed = [robot for tick in ticks for robot in tick.claimed]
    assert sorted(claimed) == robots  # each robot once
    assert ticks[-1].due == 0


def _last_seen(holder: str, ago_s: float) -> None:
    with get_engine().begin() as conn:
        conn.execute(
            text(
                "UPDATE watchers SET seen_at = now() - make_interval(secs => :s) WHERE holder = :h"
            ),
            {"s": ago_s, "h": holder},
        )


def _listed() -> list[str]:
    with get_engine().connect() as conn:
        return sorted(conn.scalars(text("SELECT holder FROM watchers")))


def test_an_instance_gone_long_is_no_longer_listed(api: Api, db: Database) -> None:
    """An instance killed (no leave()) was listed in `watchers` for ever: once it has not been
    seen for `forget_s` (10 leases, at least an interval), the next tick that looks for new
    robots forgets it. Until then it is listed but counted by no tick after a lease, so what
    /ready and /metrics say of the fleet's instances is the same either way; an instance
    that comes back is listed again by its own tick."""
    _fleet(api, db, 2)
    alive, killed = Leases(INTERVAL_S, holder="a-alive"), Leases(INTERVAL_S, holder="b-killed")
    # Each tick below comes a hair after an interval, as a real one does (ticks every
    # INTERVAL_S / 10): at exactly `now + k * INTERVAL_S`, (now + 0.4) - (now + 0.2) < 0.2 for
    # a fifth of the values time.monotonic() gives, and the tick took no interval to pass.
    step = INTERVAL_S * 1.01
    now = time.monotonic()
    killed.tick(set(), 0, now)
    assert alive.tick(set(), 0, now).watchers == 2
    assert _listed() == ["a-alive", "b-killed"]

    _last_seen("b-killed", alive.lease_s + 0.5)  # not seen for a lease: not counted, still listed
    assert alive.tick(set(), 0, now + step).watchers == 1
    assert _listed() == ["a-alive", "b-killed"]

    _last_seen("b-killed", alive.forget_s + 0.5)  # not seen for forget_s: forgotten
    assert alive.tick(set(), 0, now + 2 * step).watchers == 1
    assert _listed() == ["a-alive"]

    assert killed.tick(set(), 0, now + 2 * step).watchers == 2  # back: listed again
    assert _listed() == ["a-alive", "b-killed"]
