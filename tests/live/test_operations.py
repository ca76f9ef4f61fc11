"""Operations against a real 2-worker server: whole-server metrics, request ids in the logs,
graceful shutdown."""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.conftest import ONE_BACKEND, PG_URL

pytestmark = pytest.mark.live


@dataclass
class Served:
    """The module's server and the file its workers log to."""

    server: LiveServer
    log: Path

    def log_lines_until(self, request_id: str) -> str:
        """The log once the access line of the request `request_id` is in it (a request is
        logged as its response ends, so a client can have its answer first), up to 10 s."""
        deadline = time.monotonic() + 10
        while True:
            text = self.log.read_text()
            if f'"request_id": "{request_id}"' in text or time.monotonic() > deadline:
                return text
            time.sleep(0.02)


@pytest.fixture(scope="module", params=[ONE_BACKEND])
def served(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Served]:
    """One server per backend for the tests that only read it, count what they make, or find
    their own requests in its log by their ids: a 2-worker server with its solver pools is
    about 9 s of CPU on a slow machine. The workers append to the log file (O_APPEND), and the
    tests read it through a descriptor of their own."""
    tmp = tmp_path_factory.mktemp("operations")
    log = tmp / "server.log"
    with (
        log.open("ab") as output,
        fresh_database(request.param, tmp, PG_URL) as url,
        live_server(url, log=output) as srv,
    ):
        yield Served(srv, log)


@pytest.fixture
def server(served: Served) -> LiveServer:
    return served.server


@pytest.fixture(params=[ONE_BACKEND])
def own_server(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[LiveServer]:
    """A server of the test's own, for a test that stops it."""
    with fresh_database(request.param, tmp_path, PG_URL) as url, live_server(url) as srv:
        yield srv


def _calibrations_counted(text: str) -> float:
    return sum(
        float(v) for v in re.findall(r"^tcpcal_calibrations_total\{[^}]*\} (\S+)$", text, re.M)
    )


def test_every_scrape_counts_the_whole_server(server: LiveServer) -> None:
    with server.client() as http:
        before = _calibrations_counted(http.get("/metrics").text)
        robot = http.post("/v1/robots", json={"name": "live"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "t", "slot": 1}).json()
        for i in range(7):
            body = {"method": "manual", "tcp": {"position_mm": [0, 0, 100 + i / 10]}}
            created = http.post(f"/v1/tools/{tool['id']}/calibrations", json=body)
            assert created.status_code == 201, created.text
    counts = []
    for _ in range(20):
        # a new connection each time, so that both workers answer scrapes
        with server.client() as http:
            scrape = http.get("/metrics")
        assert scrape.status_code == 200
        counts.append(_calibrations_counted(scrape.text))
    assert counts == [before + 7.0] * 20, counts
    assert "tcpcal_http_request_duration_seconds_bucket" in scrape.text
    assert "tcpcal_db_statement_duration_seconds_count" in scrape.text
    assert "tcpcal_solve_duration_seconds_count" in scrape.text
    assert "tcpcal_db_sessions_open" in scrape.text


def test_metrics_need_a_key(server: LiveServer) -> None:
    assert httpx.get(f"{server.url}/metrics").status_code == 401


def test_one_json_log_line_per_request_carries_the_clients_request_id(served: Served) -> None:
    """Also the audit events of a calibration, which a solver process writes and logs."""
    import json

    from testbed.sim.touches import simulate_touches
    from tests.api.touches import as_poses

    srv = served.server
    with srv.client() as http:
        robot = http.post(
            "/v1/robots", json={"name": "logged"}, headers={"X-Request-ID": "cell-7.a1"}
        )
        tool = http.post(f"/v1/robots/{robot.json()['id']}/tools", json={"name": "t"})
        touches = simulate_touches(8, seed=3, tcp_mm=None)
        calibration = http.post(
            f"/v1/tools/{tool.json()['id']}/calibrations",
            json={"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(touches)},
            headers={"X-Request-ID": "cell-7.cal"},
        )
        assert calibration.status_code == 201, calibration.text
        echoed = robot.headers["X-Request-ID"]
        made = http.get("/v1/robots").headers["X-Request-ID"]
        bad = http.get("/v1/robots", headers={"X-Request-ID": "x{y}" + "z" * 200})
    text = served.log_lines_until(bad.headers["X-Request-ID"])  # the last request's line
    lines = [json.loads(line) for line in text.splitlines() if line.startswith("{")]
    assert echoed == "cell-7.a1"
    assert made
    assert made != "cell-7.a1"
    # an id that is not a plain token is replaced, never copied into a header or a log line
    assert bad.headers["X-Request-ID"] != "x{y}" + "z" * 200
    assert "x{y}" not in text
    access = [e for e in lines if e.get("event") == "request" and e["request_id"] == "cell-7.a1"]
    assert len(access) == 1, access
    line = access[0]
    assert (line["method"], line["route"], line["status"]) == ("POST", "/v1/robots", 201)
    assert line["duration_ms"] > 0
    assert line["key"] == "live-admin"
    created = [e for e in lines if e.get("event") == "robot.create" and e["request_id"] == echoed]
    assert len(created) == 1, created
    assert created[0]["resource_id"] == robot.json()["id"]
    calibrated = [e for e in lines if e.get("request_id") == "cell-7.cal"]
    assert {e["event"] for e in calibrated} == {
        "request",
        "version.create",
        "version.activate",
        "calibration.create",
    }, calibrated
    stored = next(e for e in calibrated if e["event"] == "calibration.create")
    assert stored["resource_id"] == calibration.json()["id"]
    assert stored["logger"] == "tcpcal.events"
    assert any(e.get("request_id") == bad.headers["X-Request-ID"] for e in lines)
    assert srv.admin_key not in text  # the key's name is logged, never the key
    assert all("timestamp" in e and "level" in e for e in lines)


def test_sigterm_lets_the_request_in_flight_finish(own_server: LiveServer) -> None:
    """Stopping the server (SIGTERM, as Docker and systemd do) while a client is still
    uploading a calibration: the calibration is answered and stored, then the server exits."""
    import signal
    import threading

    with own_server.client() as http:
        robot = http.post("/v1/robots", json={"name": "stop"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "t"}).json()
    body = b'{"method": "manual", "tcp": {"position_mm": [0, 0, 123]}, "note": "slow upload"}'

    def slowly() -> Iterator[bytes]:
        for i in range(0, len(body), 8):
            time.sleep(0.1)
            yield body[i : i + 8]

    answer: dict[str, httpx.Response] = {}

    def upload() -> None:
        with own_server.client() as http:
            answer["r"] = http.post(
                f"/v1/tools/{tool['id']}/calibrations",
                content=slowly(),
                headers={"Content-Type": "application/json"},
            )

    thread = threading.Thread(target=upload)
    thread.start()
    time.sleep(0.4)  # the upload has begun and takes ~1 s more
    assert own_server.process is not None
    own_server.process.send_signal(signal.SIGTERM)
    thread.join(timeout=30)
    assert answer["r"].status_code == 201, answer["r"].text
    assert answer["r"].json()["tcp"]["position_mm"] == [0, 0, 123]
    assert own_server.process.wait(timeout=30) == 0
