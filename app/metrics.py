"""Prometheus text metrics, per process: requests, latency, calibrations by outcome."""

from __future__ import annotations

import threading
from collections import defaultdict

LATENCY_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0)


class Metrics:
    """Counters and a latency histogram guarded by one lock."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.requests: dict[tuple[str, str, str], int] = defaultdict(int)
        self.latency_buckets: dict[tuple[str, str], list[int]] = {}
        self.latency_sum: dict[tuple[str, str], float] = defaultdict(float)
        self.latency_count: dict[tuple[str, str], int] = defaultdict(int)
        self.calibrations: dict[tuple[str, str], int] = defaultdict(int)

    def observe_request(self, method: str, route: str, status: int, seconds: float) -> None:
        """Count one request and its duration."""
        with self._lock:
            self.requests[(method, route, str(status))] += 1
            key = (method, route)
            buckets = self.latency_buckets.setdefault(key, [0] * len(LATENCY_BUCKETS))
            for i, bound in enumerate(LATENCY_BUCKETS):
                if seconds <= bound:
                    buckets[i] += 1
            self.latency_sum[key] += seconds
            self.latency_count[key] += 1

    def observe_calibration(self, method: str, status: str) -> None:
        """Count one stored calibration by method and status."""
        with self._lock:
            self.calibrations[(method, status)] += 1

    def render(self) -> str:
        """The Prometheus text exposition of everything counted so far."""
        out = [
            "# HELP tcpcal_http_requests_total HTTP requests by method, route and status.",
            "# TYPE tcpcal_http_requests_total counter",
        ]
        with self._lock:
            for (method, route, status), n in sorted(self.requests.items()):
                out.append(
                    f'tcpcal_http_requests_total{{method="{method}",route="{route}",'
                    f'status="{status}"}} {n}'
                )
            out += [
                "# HELP tcpcal_http_request_duration_seconds Request latency.",
                "# TYPE tcpcal_http_request_duration_seconds histogram",
            ]
            for (method, route), buckets in sorted(self.latency_buckets.items()):
                labels = f'method="{method}",route="{route}"'
                for bound, n in zip(LATENCY_BUCKETS, buckets, strict=True):
                    out.append(
                        f'tcpcal_http_request_duration_seconds_bucket{{{labels},le="{bound}"}} {n}'
                    )
                count = self.latency_count[(method, route)]
                out.append(
                    f'tcpcal_http_request_duration_seconds_bucket{{{labels},le="+Inf"}} {count}'
                )
                out.append(
                    f"tcpcal_http_request_duration_seconds_sum{{{labels}}} "
                    f"{self.latency_sum[(method, route)]:.6f}"
                )
                out.append(f"tcpcal_http_request_duration_seconds_count{{{labels}}} {count}")
            out += [
                "# HELP tcpcal_calibrations_total Stored calibrations by method and status.",
                "# TYPE tcpcal_calibrations_total counter",
            ]
            for (method, status), n in sorted(self.calibrations.items()):
                out.append(f'tcpcal_calibrations_total{{method="{method}",status="{status}"}} {n}')
        return "\n".join(out) + "\n"


METRICS = Metrics()
