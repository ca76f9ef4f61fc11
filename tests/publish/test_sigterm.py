"""`tcpcal publish` stops within a second of SIGTERM (docs/publishing.md), whatever it is
doing: waiting out a broker that is down (paho's reconnect backoff: 1 s, then 2 s, 4 s ...
up to 30 s), in the middle of a reconnection the broker does not answer (TCP accepted and
no CONNACK; or no answer to the TCP connection at all, as from a host that is down), with a
batch waiting for PUBACKs from a hung broker, and while its first connection waits. (Idle
with the broker up: tests/publish/test_mqtt.py.) A real process, a real signal, the time to
its exit measured from the signal."""

from __future__ import annotations

import os
import signal
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import Api, one_backend
from tests.polling import wait_for
from tests.publish.mqtt_harness import (
    Broker,
    Publisher,
    Subscriber,
    free_port,
    needs_mosquitto,
)

pytestmark = [needs_mosquitto, pytest.mark.live]

#: docs/publishing.md: "SIGTERM stops it within a second".
LIMIT_S = 1.0


class SilentBroker:
    """A listener on a port that accepts connections and never answers: an MQTT connection
    stays in progress (CONNECT sent, no CONNACK) for as long as it is up."""

    def __init__(self, port: int) -> None:
        self.socket = socket.create_server(("127.0.0.1", port))
        self.accepted: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.socket.accept()
            except OSError:  # closed
                return
            self.accepted.append(conn)

    def close(self) -> None:
        self.socket.close()
        for conn in self.accepted:
            conn.close()


class DeadHost:
    """A port whose TCP handshakes go unanswered, as a host that is down: a listener with a
    full accept queue (backlog 0, one connection queued and never accepted) drops the SYNs
    of every further connect(2), which then waits for its timeout."""

    def __init__(self, port: int) -> None:
        self.socket = socket.create_server(("127.0.0.1", port), backlog=0)
        self.queued = socket.create_connection(("127.0.0.1", port), timeout=1)

    def close(self) -> None:
        self.queued.close()
        self.socket.close()

    def knocking(self) -> bool:
        """Whether a connect(2) to the port waits for its handshake now (a socket in state
        SYN_SENT, 02, towards it in /proc/net/tcp: proc(5))."""
        port = f"{self.socket.getsockname()[1]:04X}"
        rows = Path("/proc/net/tcp").read_text().splitlines()[1:]
        return any(r.split()[2].endswith(f":{port}") and r.split()[3] == "02" for r in rows)


@pytest.fixture
def started() -> Iterator[list[Publisher]]:
    publishers: list[Publisher] = []
    yield publishers
    for p in publishers:
        p.kill()


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path)
    b.start()
    yield b
    if b.process is not None:
        b.process.send_signal(signal.SIGCONT)  # a test may leave it stopped
    b.stop()


def _publisher(
    tmp: Path, url: str, started: list[Publisher], prefix: str = "sigterm", **env: str
) -> Publisher:
    publisher = Publisher(tmp, os.environ["TCPCAL_DATABASE_URL"], url, prefix, **env).start()
    started.append(publisher)
    return publisher


def _online_publisher(tmp: Path, broker: Broker, started: list[Publisher]) -> Publisher:
    sub = Subscriber(broker, "sigterm")
    publisher = _publisher(tmp, broker.url(), started)
    try:
        wait_for(lambda: any(m.payload == b"online" for m in sub.on("status")), 30, "online")
    finally:
        sub.close()
    return publisher


def _seconds_to_exit(publisher: Publisher) -> float:
    """SIGTERM, then the seconds until the process is gone; it must exit 0 (stopped as
    asked, not failed)."""
    seconds = publisher.terminate()
    assert publisher.wait(1) == 0, publisher.output()
    return seconds


@one_backend
@pytest.mark.parametrize("after_s", [0.0, 1.05, 3.05])
def test_sigterm_while_the_broker_is_down(
    api: Api, broker: Broker, tmp_path: Path, started: list[Publisher], after_s: float
) -> None:
    """A killed broker: paho's network thread sleeps 1 s, tries (refused at once), sleeps
    2 s, tries, sleeps 4 s; the signal comes at the start of each of those sleeps."""
    publisher = _online_publisher(tmp_path, broker, started)
    broker.kill()
    wait_for(lambda: "disconnected from" in publisher.output(), 10, "the disconnection")
    time.sleep(after_s)
    seconds = _seconds_to_exit(publisher)
    assert seconds < LIMIT_S, f"SIGTERM took {seconds:.2f} s with the broker down"


@one_backend
def test_sigterm_in_a_reconnection_the_broker_does_not_answer(
    api: Api, broker: Broker, tmp_path: Path, started: list[Publisher]
) -> None:
    publisher = _online_publisher(tmp_path, broker, started)
    broker.kill()
    silent = SilentBroker(broker.port)
    try:
        wait_for(lambda: bool(silent.accepted), 10, "a reconnection attempt")
        time.sleep(0.1)  # CONNECT sent, no CONNACK coming
        seconds = _seconds_to_exit(publisher)
        assert seconds < LIMIT_S, f"SIGTERM took {seconds:.2f} s mid-reconnection"
    finally:
        silent.close()


@one_backend
def test_sigterm_in_a_reconnection_to_a_host_that_is_down(
    api: Api, broker: Broker, tmp_path: Path, started: list[Publisher]
) -> None:
    """The reconnection's connect(2) waits TCPCAL_MQTT_CONNECT_TIMEOUT_S (here 5 s) for a
    handshake that never comes; the signal comes during it."""
    publisher = _online_publisher(tmp_path, broker, started)
    broker.kill()
    dead = DeadHost(broker.port)
    try:
        wait_for(lambda: "disconnected from" in publisher.output(), 10, "the disconnection")
        time.sleep(1.5)  # the first retry (after 1 s) is waiting for its handshake
        seconds = _seconds_to_exit(publisher)
        assert seconds < LIMIT_S, f"SIGTERM took {seconds:.2f} s connecting to a dead host"
    finally:
        dead.close()


@one_backend
def test_sigterm_with_a_batch_waiting_for_a_hung_broker(
    api: Api, broker: Broker, tmp_path: Path, started: list[Publisher]
) -> None:
    """The broker stopped (SIGSTOP) with its connection open: the batch's PUBACKs and the
    clean stop's `offline` are never acknowledged."""
    publisher = _online_publisher(tmp_path, broker, started)
    assert broker.process is not None
    broker.process.send_signal(signal.SIGSTOP)
    api.robot("r-while-hung")  # an outbox row: a batch the broker will not acknowledge
    time.sleep(0.5)
    seconds = _seconds_to_exit(publisher)
    assert seconds < LIMIT_S, f"SIGTERM took {seconds:.2f} s with the broker hung"


@one_backend
@pytest.mark.parametrize("peer", ["silent", "dead"])
def test_sigterm_while_the_first_connection_waits(
    api: Api, tmp_path: Path, started: list[Publisher], peer: str
) -> None:
    """At start-up, a broker that accepts and does not answer, or a host that does not
    answer at all: the publisher would wait TCPCAL_MQTT_CONNECT_TIMEOUT_S (30 s here) for
    it, unless told to stop; stopped so, it exits 0 (nothing was wrong with its settings)."""
    port = free_port()
    other = SilentBroker(port) if peer == "silent" else DeadHost(port)
    try:
        publisher = _publisher(
            tmp_path, f"mqtt://127.0.0.1:{port}", started, TCPCAL_MQTT_CONNECT_TIMEOUT_S="30"
        )
        if isinstance(other, SilentBroker):
            wait_for(lambda: bool(other.accepted), 30, "the publisher's connection")
        else:
            wait_for(other.knocking, 30, "the publisher's connection")
        time.sleep(0.2)
        seconds = _seconds_to_exit(publisher)
        assert seconds < LIMIT_S, f"SIGTERM took {seconds:.2f} s while connecting ({peer})"
    finally:
        other.close()
