"""Fleet state in /metrics, read from the database at scrape time.

Request counters live in each worker (app.metrics); the fleet's state is the database's, so
a custom collector (prometheus-client's "custom collector" pattern: a `collect()` that yields
metric families) reads it once per scrape, whichever worker answers, and every worker reports
the same numbers. Alert rules built on these names: deploy/prometheus/tcpcal.rules.yml.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator
from datetime import UTC, datetime

from prometheus_client.core import GaugeMetricFamily, Metric
from prometheus_client.registry import Collector
from sqlalchemy.exc import SQLAlchemyError

from app.services.fleet.gauges import FleetGauges, SubjectGauges, read_fleet_gauges
from app.storage.db import session_scope

log = logging.getLogger(__name__)


class FleetCollector(Collector):
    """Yields the fleet gauges; a database that does not answer gives
    tcpcal_fleet_gauges_up 0 (and no fleet gauges) instead of failing the scrape."""

    def describe(self) -> Iterable[Metric]:
        # Nothing up front: registering the collector must not query the database.
        return ()

    def collect(self) -> Iterator[Metric]:
        """One read of the fleet, as metric families."""
        up = GaugeMetricFamily(
            "tcpcal_fleet_gauges_up", "1 when the fleet gauges could be read from the database."
        )
        try:
            with session_scope(write=False) as session:
                gauges = read_fleet_gauges(session, now=datetime.now(UTC))
        except SQLAlchemyError as exc:
            log.warning("fleet gauges not read: %s", type(exc).__name__)
            up.add_metric([], 0.0)
            yield up
            return
        up.add_metric([], 1.0)
        yield up
        yield from fleet_families(gauges)


def fleet_families(gauges: FleetGauges) -> Iterator[Metric]:
    """The metric families of one reading of the fleet: each subject's, then the
    publisher's."""
    for subject in gauges.subjects:
        yield from _subject_families(subject)
    yield from _publisher_families(gauges)


def _subject_families(gauges: SubjectGauges) -> Iterator[Metric]:
    """A subject's families, named by its declaration (a tool's: tcpcal_fleet_tools_attention,
    tcpcal_tool_last_check_age_seconds with labels tool_id, robot, tool)."""
    kind, plural = gauges.served.subject.kind, gauges.served.subject.plural
    attention = GaugeMetricFamily(
        f"tcpcal_fleet_{plural}_attention",
        f"Live {plural} having each attention code (a {kind} with two codes counts in both).",
        labels=["code"],
    )
    for code, n in sorted(gauges.attention.items()):
        attention.add_metric([code], float(n))
    yield attention

    controller = GaugeMetricFamily(
        f"tcpcal_fleet_{plural}_controller_state",
        f"Live {plural} by the state of their controller's copy (none: no controller).",
        labels=["state"],
    )
    for state, n in sorted(gauges.controller.items()):
        controller.add_metric([state], float(n))
    yield controller
    yield from _age_families(gauges)


def _publisher_families(gauges: FleetGauges) -> Iterator[Metric]:
    age = GaugeMetricFamily(
        "tcpcal_outbox_oldest_undelivered_age_seconds",
        "Seconds the oldest change not yet published (MQTT, OPC UA) has waited; 0: none waits.",
    )
    age.add_metric([], gauges.outbox_oldest_age_s)
    yield age
    waiting = GaugeMetricFamily(
        "tcpcal_outbox_undelivered", "Changes waiting for the publisher (outbox rows)."
    )
    waiting.add_metric([], float(gauges.outbox_undelivered))
    yield waiting
    running = GaugeMetricFamily(
        "tcpcal_publisher_running",
        "1 while a publisher (tcpcal publish) holds the fleet's publisher lock.",
    )
    running.add_metric([], 1.0 if gauges.publisher_running else 0.0)
    yield running


def _age_families(gauges: SubjectGauges) -> Iterator[Metric]:
    kind, plural = gauges.served.subject.kind, gauges.served.subject.plural
    labels = [f"{kind}_id", "robot", kind]
    total = GaugeMetricFamily(f"tcpcal_fleet_{plural}", f"Live {plural} (of live robots).")
    total.add_metric([], float(len(gauges.items)))
    yield total
    calibration = GaugeMetricFamily(
        f"tcpcal_{kind}_last_calibration_age_seconds",
        f"Seconds since the {kind}'s newest calibration (no series: never calibrated).",
        labels=labels,
    )
    check = GaugeMetricFamily(
        f"tcpcal_{kind}_last_check_age_seconds",
        f"Seconds since the {kind}'s newest check (no series: never checked).",
        labels=labels,
    )
    flagged = GaugeMetricFamily(
        f"tcpcal_{kind}_attention",
        f"1 for each attention code a {kind} has (only {plural} that have one: alerts name "
        f"the {kind}).",
        labels=[*labels, "code"],
    )
    for t in gauges.items:
        values = [t.subject_id, t.robot, t.name]
        if t.calibration_age_s is not None:
            calibration.add_metric(values, t.calibration_age_s)
        if t.check_age_s is not None:
            check.add_metric(values, t.check_age_s)
        for code in t.attention:
            flagged.add_metric([*values, code], 1.0)
    yield calibration
    yield check
    yield flagged


#: The one collector /metrics adds to the process's (or the workers') metrics.
FLEET = FleetCollector()
