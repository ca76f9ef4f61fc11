"""Prometheus metrics with prometheus-client, whole-server across worker processes.

`tcpcal serve` points PROMETHEUS_MULTIPROC_DIR at an empty directory before the workers
start; each worker then writes its samples to files there and every scrape of /metrics,
whichever worker answers it, adds up all of them (prometheus-client's multiprocess mode).
Without that variable (tests, a single in-process app) the process's own registry is served.
"""

from __future__ import annotations

import os

from prometheus_client import (
    CONTENT_TYPE_LATEST,
    REGISTRY,
    CollectorRegistry,
    Counter,
    Gauge,
    Histogram,
    generate_latest,
    multiprocess,
)
from prometheus_client.registry import Collector

MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"
LATENCY_BUCKETS = (0.002, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0)

REQUESTS = Counter(
    "tcpcal_http_requests",
    "HTTP requests by method, route and status.",
    ["method", "route", "status"],
)
REQUEST_SECONDS = Histogram(
    "tcpcal_http_request_duration_seconds",
    "Request latency by method and route template.",
    ["method", "route"],
    buckets=LATENCY_BUCKETS,
)
CALIBRATIONS = Counter(
    "tcpcal_calibrations", "Stored calibrations by method and status.", ["method", "status"]
)
SOLVE_SECONDS = Histogram(
    "tcpcal_solve_duration_seconds",
    "Time to solve and grade a submission (stored or not), by method.",
    ["method"],
    buckets=LATENCY_BUCKETS,
)
DB_SECONDS = Histogram(
    "tcpcal_db_statement_duration_seconds",
    "Time the database took per SQL statement.",
    buckets=(0.0005, 0.001, 0.002, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 1.0),
)
DEPLOYMENTS = Counter(
    "tcpcal_deployments",
    "Deployments to robot controllers by protocol and status "
    "(verified, not_written, unverified, mismatch).",
    ["protocol", "status"],
)
CONTROLLER_STATE_CHANGES = Counter(
    "tcpcal_controller_state_changes",
    "Changes of a tool's controller state, by the state entered (in_sync, drifted, unreachable).",
    ["state"],
)
RECONCILES = Counter(
    "tcpcal_reconciles",
    "Robots reconciled with their controller, by who asked (api, watcher) and the robot's state.",
    ["trigger", "state"],
)
WATCHED_ROBOTS = Gauge(
    "tcpcal_watcher_robots",
    "Robots this instance's controller watcher reads each round (0: it watches none).",
    multiprocess_mode="livesum",
)
WATCHER_CONCURRENCY = Gauge(
    "tcpcal_watcher_concurrency",
    "Controllers the watcher reads at once, sized each round from the fleet, the interval "
    "and the reads' median time (reads stalled past 4 times that median apart).",
    multiprocess_mode="livesum",
)
WATCHER_ROUND_SECONDS = Gauge(
    "tcpcal_watcher_round_seconds",
    "How long the watcher's last round took, from its start to its last read's store.",
    multiprocess_mode="max",
)
WATCHER_OVERRUNS = Counter(
    "tcpcal_watcher_rounds_overrun",
    "Watcher rounds whose interval ended before every robot's read began (PostgreSQL: the "
    "fleet's round, counted by one instance).",
)
WATCHER_INTERVAL_NEEDED = Gauge(
    "tcpcal_watcher_interval_needed_seconds",
    "The interval the last overrun round's reads would have fitted at the pool's size "
    "(TCPCAL_RECONCILE_INTERVAL_S at least this, or more concurrency).",
    multiprocess_mode="max",
)
SESSIONS_OPEN = Gauge(
    "tcpcal_db_sessions_open",
    "Database sessions (units of work) open right now, over all workers.",
    multiprocess_mode="livesum",
)


def render(*collectors: Collector) -> tuple[bytes, str]:
    """The exposition of the whole server, and its content type; `collectors` (read at
    scrape time, e.g. the fleet's state from the database) are added to it."""
    if os.environ.get(MULTIPROC_ENV):
        registry = CollectorRegistry()
        multiprocess.MultiProcessCollector(registry)  # type: ignore[no-untyped-call]
        body = generate_latest(registry)
    else:
        body = generate_latest(REGISTRY)
    if collectors:
        extra = CollectorRegistry(auto_describe=False)
        for collector in collectors:
            extra.register(collector)
        body += generate_latest(extra)
    return body, CONTENT_TYPE_LATEST
