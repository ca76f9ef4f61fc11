"""A real Mosquitto on a free loopback port, a real paho subscriber, and `tcpcal publish` as
a child process: what the publisher tests drive.

Mosquitto 2 configuration: https://mosquitto.org/man/mosquitto-conf-5.html (listener,
allow_anonymous, password_file, persistence, autosave_interval).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from tests.polling import wait_for

MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
MOSQUITTO_PASSWD = shutil.which("mosquitto_passwd") or "/usr/bin/mosquitto_passwd"
REPO = Path(__file__).resolve().parents[2]

INSTALL = "apt-get install mosquitto mosquitto-clients"


def mosquitto_required(environ: Mapping[str, str]) -> bool:
    """Whether a missing Mosquitto fails the tests that need one instead of skipping them:
    under CI (`CI` set, as .ci/run and CI services do) or with TCPCAL_REQUIRE_MOSQUITTO, as
    a missing browser or node-opcua fails theirs (tests/browser/conftest.py): a CI run must
    never pass with its broker tests silently skipped."""
    return bool(environ.get("CI") or environ.get("TCPCAL_REQUIRE_MOSQUITTO"))


def skip_without_mosquitto(installed: bool, environ: Mapping[str, str]) -> bool:
    """Whether the tests that need a broker are skipped (only where it is not required)."""
    return not installed and not mosquitto_required(environ)


#: Skips the tests that need a broker when Mosquitto is not installed, except where it is
#: required: there they run, and `Broker` fails them saying what to install.
needs_mosquitto = pytest.mark.skipif(
    skip_without_mosquitto(Path(MOSQUITTO).exists(), os.environ),
    reason=f"mosquitto is not installed ({INSTALL})",
)


def require_mosquitto() -> None:
    """Fail the test, saying what to install, when there is no Mosquitto (reached only where
    it is required: needs_mosquitto skips the test elsewhere)."""
    if not Path(MOSQUITTO).exists():
        pytest.fail(
            "mosquitto is required here (CI or TCPCAL_REQUIRE_MOSQUITTO is set) and there is "
            f"none at {MOSQUITTO}: {INSTALL}"
        )


def free_port() -> int:
    """A loopback port nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Broker:
    """One Mosquitto process; `kill()` (SIGKILL) and `start()` again on the same port."""

    def __init__(
        self,
        tmp: Path,
        *,
        users: dict[str, str] | None = None,
        persist: bool = False,
        tls: bool = False,
    ):
        require_mosquitto()
        self.port = free_port()
        self.dir = tmp / f"mosquitto-{self.port}"
        self.dir.mkdir()
        lines = [f"listener {self.port} 127.0.0.1", "log_dest stderr"]
        self.ca_file: Path | None = None
        if tls:
            self.ca_file, cert, key = make_certificates(self.dir)
            lines += [f"cafile {self.ca_file}", f"certfile {cert}", f"keyfile {key}"]
        if os.geteuid() == 0:  # as root it would switch to the mosquitto user, who cannot
            lines.append("user root")  # read the password file in pytest's private tmp
        if users:
            passwd = self.dir / "passwd"
            for i, (user, password) in enumerate(users.items()):
                flags = ["-b", "-c"] if i == 0 else ["-b"]
                subprocess.run(
                    [MOSQUITTO_PASSWD, *flags, str(passwd), user, password],
                    check=True,
                    capture_output=True,
                )
            lines += ["allow_anonymous false", f"password_file {passwd}"]
        else:
            lines.append("allow_anonymous true")
        if persist:
            lines += [
                "persistence true",
                f"persistence_location {self.dir}/",
                "autosave_interval 1",
            ]
        self.config = self.dir / "mosquitto.conf"
        self.config.write_text("\n".join(lines) + "\n")
        self.log = self.dir / "mosquitto.log"
        self.process: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        with self.log.open("ab") as log:
            self.process = subprocess.Popen(
                [MOSQUITTO, "-c", str(self.config)], stdout=log, stderr=subprocess.STDOUT
            )
        wait_for(self._listening, 10, f"mosquitto on port {self.port}")

    def _listening(self) -> bool:
        assert self.process is not None
        if self.process.poll() is not None:
            raise AssertionError(f"mosquitto exited: {self.log.read_text()[-2000:]}")
        try:
            socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
        except OSError:
            return False
        return True

    def kill(self) -> None:
        """SIGKILL: no clean shutdown, nothing saved that was not saved already."""
        assert self.process is not None
        self.process.kill()
        self.process.wait(10)
        self.process = None

    def stop(self) -> None:
        if self.process is not None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)
            self.process = None

    def url(self, user: str | None = None, password: str | None = None) -> str:
        auth = "" if user is None else f"{user}:{password}@"
        scheme = "mqtts" if self.ca_file else "mqtt"
        return f"{scheme}://{auth}127.0.0.1:{self.port}"


def make_certificates(directory: Path) -> tuple[Path, Path, Path]:
    """A throwaway CA and a server certificate for 127.0.0.1 signed by it (openssl(1)):
    (CA certificate, server certificate, server key)."""
    ca_key, ca, key, csr, cert = (
        directory / n for n in ("ca.key", "ca.crt", "server.key", "server.csr", "server.crt")
    )
    ext = directory / "san.ext"
    ext.write_text("subjectAltName=IP:127.0.0.1\nbasicConstraints=CA:FALSE\n")
    commands: list[list[object]] = [
        ["req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", ca_key, "-out", ca],
        ["req", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", csr],
        ["x509", "-req", "-in", csr, "-CA", ca, "-CAkey", ca_key, "-CAcreateserial"],
    ]
    commands[0] += ["-days", "2", "-subj", "/CN=tcpcal test CA"]
    commands[1] += ["-subj", "/CN=127.0.0.1"]
    commands[2] += ["-out", cert, "-days", "2", "-extfile", ext]
    for command in commands:
        subprocess.run(["openssl", *map(str, command)], check=True, capture_output=True)
    return ca, cert, key


@dataclass(frozen=True)
class Received:
    topic: str
    payload: bytes
    retain: bool
    at: float

    def json(self) -> Any:
        return json.loads(self.payload)


class Subscriber:
    """A paho client that records every message under `{prefix}/#`. `persistent`: a fixed
    client id and a session the broker keeps while it is away (QoS 1 messages queued)."""

    def __init__(self, broker: Broker, prefix: str, *, persistent: bool = False, **auth: str):
        """`auth`: user and password, when the broker asks for them."""
        self.prefix = prefix
        self.messages: list[Received] = []
        self.lock = threading.Lock()
        self.subscribed = threading.Event()
        client_id = f"test-sub-{uuid.uuid4().hex[:8]}"
        self.client = mqtt.Client(
            callback_api_version=CallbackAPIVersion.VERSION2,
            client_id=client_id,
            clean_session=not persistent,
            protocol=mqtt.MQTTv311,
        )
        if auth:
            self.client.username_pw_set(auth["user"], auth["password"])
        if broker.ca_file is not None:
            self.client.tls_set(ca_certs=str(broker.ca_file))
        self.client.reconnect_delay_set(1, 1)
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self.client.on_subscribe = lambda *_: self.subscribed.set()
        self.client.connect("127.0.0.1", broker.port, keepalive=10)
        self.client.loop_start()
        assert self.subscribed.wait(10), "the test subscriber was not subscribed"

    def _on_connect(self, client: mqtt.Client, *_: Any) -> None:
        client.subscribe(f"{self.prefix}/#", qos=1)

    def _on_message(self, _: mqtt.Client, __: Any, message: mqtt.MQTTMessage) -> None:
        with self.lock:
            self.messages.append(
                Received(
                    message.topic, bytes(message.payload), bool(message.retain), time.monotonic()
                )
            )

    def on(self, topic: str) -> list[Received]:
        with self.lock:
            return [m for m in self.messages if m.topic == f"{self.prefix}/{topic}"]

    def events(self) -> list[dict[str, Any]]:
        return [m.json() for m in self.on("events")]

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


class Publisher:
    """`tcpcal publish` in a child process (this worktree's code)."""

    def __init__(self, tmp: Path, database_url: str, mqtt_url: str, prefix: str, **env: str):
        self.log = tmp / f"publisher-{uuid.uuid4().hex[:6]}.log"
        self.env = {
            **os.environ,
            "PYTHONPATH": str(REPO),
            "TCPCAL_DATABASE_URL": database_url,
            "TCPCAL_MQTT_URL": mqtt_url,
            "TCPCAL_MQTT_PREFIX": prefix,
            "TCPCAL_LOG_FORMAT": "console",
            "TCPCAL_OUTBOX_KEEP_S": "0",
            **env,
        }
        self.process: subprocess.Popen[bytes] | None = None

    def start(self) -> Publisher:
        with self.log.open("ab") as log:
            self.process = subprocess.Popen(
                [sys.executable, "-c", "from app.cli import main; main()", "publish"],
                env=self.env,
                stdout=log,
                stderr=subprocess.STDOUT,
                cwd=REPO,
            )
        return self

    def output(self) -> str:
        return self.log.read_text(errors="replace")

    def wait(self, timeout: float) -> int:
        assert self.process is not None
        return self.process.wait(timeout)

    def kill(self) -> None:
        """SIGKILL: no clean shutdown."""
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait(10)

    def terminate(self) -> float:
        """SIGTERM; the seconds it took to exit."""
        assert self.process is not None
        started = time.monotonic()
        self.process.send_signal(signal.SIGTERM)
        self.process.wait(10)
        return time.monotonic() - started


def run_publisher_once(database_url: str, mqtt_url: str, timeout: float = 60) -> tuple[int, str]:
    """Run `tcpcal publish` expecting it to exit by itself: (exit code, output)."""
    env = {
        **os.environ,
        "PYTHONPATH": str(REPO),
        "TCPCAL_DATABASE_URL": database_url,
        "TCPCAL_MQTT_URL": mqtt_url,
        "TCPCAL_MQTT_CONNECT_TIMEOUT_S": "3",
    }
    done = subprocess.run(
        [sys.executable, "-c", "from app.cli import main; main()", "publish"],
        env=env,
        capture_output=True,
        timeout=timeout,
        cwd=REPO,
    )
    return done.returncode, (done.stdout + done.stderr).decode(errors="replace")


class Commander:
    """A cell PLC as an MQTT 5 client (paho): sends re-check commands with the API key in the
    user property `authorization`, and records every reply under `{prefix}/replies/#` with
    its user properties (MQTT 5.0, 3.3.2.3.7)."""

    def __init__(self, broker: Broker, prefix: str):
        self.prefix = prefix
        self.replies: list[tuple[str, bytes, dict[str, str]]] = []
        self.lock = threading.Lock()
        subscribed = threading.Event()
        self.client = mqtt.Client(
            callback_api_version=CallbackAPIVersion.VERSION2,
            client_id=f"test-plc-{uuid.uuid4().hex[:8]}",
            protocol=mqtt.MQTTv5,
        )
        self.client.on_message = self._on_message
        self.client.on_connect = self._on_connect  # subscribed again after a broker restart
        self.client.on_subscribe = lambda *_: subscribed.set()
        self.client.reconnect_delay_set(1, 1)
        self.client.connect("127.0.0.1", broker.port, keepalive=10)
        self.client.loop_start()
        assert subscribed.wait(10), "the test PLC was not subscribed"

    def _on_connect(self, client: mqtt.Client, *_: Any) -> None:
        client.subscribe(f"{self.prefix}/replies/#", qos=1)

    def _on_message(self, _: mqtt.Client, __: Any, message: mqtt.MQTTMessage) -> None:
        said = dict(getattr(message.properties, "UserProperty", None) or [])
        with self.lock:
            self.replies.append((message.topic, bytes(message.payload), said))

    def send(self, body: bytes | dict[str, Any], authorization: str | None) -> None:
        """Publish a command (QoS 1), `authorization` in its user property when given."""
        properties = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
        if authorization is not None:
            properties.UserProperty = [("authorization", authorization)]
        payload = body if isinstance(body, bytes) else json.dumps(body).encode()
        info = self.client.publish(
            f"{self.prefix}/commands/recheck", payload, qos=1, properties=properties
        )
        info.wait_for_publish(5)

    def on(self, request_id: str) -> list[tuple[bytes, dict[str, str]]]:
        """The replies on `{prefix}/replies/{request_id}`: (payload, user properties)."""
        topic = f"{self.prefix}/replies/{request_id}"
        with self.lock:
            return [(payload, said) for t, payload, said in self.replies if t == topic]

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()
