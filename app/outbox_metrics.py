"""The outbox in /metrics: how far the publisher (`tcpcal publish`) is behind.

Read from the database at scrape time by a custom collector (the database is the same for
every worker, so any worker's scrape gives the fleet's number). A publisher that is down,
or cannot reach its broker, makes `tcpcal_outbox_oldest_undelivered_age_seconds` grow:
alert on it (deploy/prometheus). The API never waits for the publisher.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator

from prometheus_client.core import GaugeMetricFamily, Metric
from prometheus_client.registry import Collector
from sqlalchemy.exc import SQLAlchemyError

from app.db import session_scope
from app.services.outbox import oldest_undelivered_age, undelivered_count

log = logging.getLogger(__name__)


def outbox_families() -> Iterator[Metric]:
    """The outbox's gauges (nothing when the database does not answer)."""
    try:
        with session_scope(write=False) as session:
            age = oldest_undelivered_age(session)
            waiting = undelivered_count(session)
    except SQLAlchemyError as exc:
        log.warning("outbox gauges not read: %s", type(exc).__name__)
        return
    oldest = GaugeMetricFamily(
        "tcpcal_outbox_oldest_undelivered_age_seconds",
        "Seconds since the oldest change not yet delivered to the plant was committed "
        "(0: the publisher is up to date).",
    )
    oldest.add_metric([], age)
    yield oldest
    count = GaugeMetricFamily(
        "tcpcal_outbox_undelivered", "Changes committed and not yet delivered to the plant."
    )
    count.add_metric([], float(waiting))
    yield count


class OutboxCollector(Collector):
    """The outbox gauges, read at each scrape."""

    def describe(self) -> Iterable[Metric]:
        return ()  # registering must not query the database

    def collect(self) -> Iterator[Metric]:
        return outbox_families()


#: The collector /metrics adds (app.api.health).
OUTBOX = OutboxCollector()
