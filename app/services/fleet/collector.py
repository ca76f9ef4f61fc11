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

from app.services.fleet.gauges import FleetGauges, read_fleet_gauges
from app.storage.db import session_scope

log = logging.getLogger(__name__)

TOOL_LABELS = ("tool_id", "robot", "tool")


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
    """The metric families of one reading of the fleet."""
    attention = GaugeMetricFamily(
        "tcpcal_fleet_tools_attention",
        "Live tools having each attention code (a tool with two codes counts in both).",
        labels=["code"],
    )
    for code, n in sorted(gauges.attention.items()):
        attention.add_metric([code], float(n))
    yield attention

    controller = GaugeMetricFamily(
        "tcpcal_fleet_tools_controller_state",
        "Live tools by the state of their controller's copy (none: no controller).",
        labels=["state"],
    )
    for state, n in sorted(gauges.controller.items()):
        controller.add_metric([state], float(n))
    yield controller

    yield from _tool_families(gauges)
    yield from _publisher_families(gauges)


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


def _tool_families(gauges: FleetGauges) -> Iterator[Metric]:
    total = GaugeMetricFamily("tcpcal_fleet_tools", "Live tools (of live robots).")
    total.add_metric([], float(len(gauges.tools)))
    yield total
    calibration = GaugeMetricFamily(
        "tcpcal_tool_last_calibration_age_seconds",
        "Seconds since the tool's newest calibration (no series: never calibrated).",
        labels=list(TOOL_LABELS),
    )
    check = GaugeMetricFamily(
        "tcpcal_tool_last_check_age_seconds",
        "Seconds since the tool's newest check (no series: never checked).",
        labels=list(TOOL_LABELS),
    )
    flagged = GaugeMetricFamily(
        "tcpcal_tool_attention",
        "1 for each attention code a tool has (only tools that have one: alerts name the tool).",
        labels=[*TOOL_LABELS, "code"],
    )
    for t in gauges.tools:
        labels = [t.tool_id, t.robot, t.tool]
        if t.calibration_age_s is not None:
            calibration.add_metric(labels, t.calibration_age_s)
        if t.check_age_s is not None:
            check.add_metric(labels, t.check_age_s)
        for code in t.attention:
            flagged.add_metric([*labels, code], 1.0)
    yield calibration
    yield check
    yield flagged


#: The one collector /metrics adds to the process's (or the workers') metrics.
FLEET = FleetCollector()
