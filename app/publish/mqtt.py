"""The MQTT sink: the outbox as topics of a broker, with paho-mqtt (>= 2).

References: MQTT Version 3.1.1, OASIS Standard (retained messages 3.3.1.3, QoS 1 delivery
and PUBACK 4.3.2, Will Message 3.1.2.5, CONNACK return codes 3.2.2.3),
https://docs.oasis-open.org/mqtt/mqtt/v3.1.1/os/mqtt-v3.1.1-os.html ; Eclipse Paho Python
client 2.x, https://eclipse.dev/paho/files/paho.mqtt.python/html/client.html .

Topics (API.md v1.2, prefix TCPCAL_MQTT_PREFIX, default `tcpcal`):
- `{prefix}/tools/{tool_id}/tcp` (each subject's: `state_topic`), retained, QoS 1: the
  document GET /v1/tools/{tool_id}/tcp
  serves, with its `etag`, the active version's `status` and its `activation` (kind,
  reason, at, by: API.md v1.3); an empty retained message (which clears the topic) when the tool
  is archived or has no active version;
- `{prefix}/events`, QoS 1, not retained: one JSON object per outbox row (with `kind` and
  `reason`: app.services.audit.outbox.event_of);
- `{prefix}/status`, retained: `online` once connected, `offline` as the last will and on a
  clean stop;
- with TCPCAL_MQTT_COMMANDS=true, it also subscribes to `{prefix}/commands/recheck` and
  `{prefix}/commands/recheck-frame` (QoS 1) and answers on `{prefix}/replies/{request_id}`
  (app.publish.commands). The connection is then MQTT 5 (its user properties carry the
  command's API key; MQTT 5.0, OASIS Standard,
  https://docs.oasis-open.org/mqtt/mqtt/v5.0/mqtt-v5.0.html 3.3.2.3.7), otherwise 3.1.1, which
  every broker speaks. The subscription is made on every (re)connection, the session being
  clean.

The client id is fixed per prefix (`tcpcal-publisher-{prefix}`): a restarted publisher takes
over the session of one killed with SIGKILL at once (the broker drops the old connection and
sends its will, then the new one says `online`), rather than the dead connection's will
arriving later and leaving `offline` retained. The session is clean: the outbox, not the
broker, remembers what was not acknowledged. paho's network thread reconnects with backoff
(1 s doubling to 30 s); each reconnection changes `connection_id()`, so the runner sends the
state of every live tool again (a broker restarted without persistence lost the retained
messages).
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING
from urllib.parse import unquote, urlsplit

import paho.mqtt.client as mqtt
from paho.mqtt.client import ConnectFlags, DisconnectFlags
from paho.mqtt.enums import CallbackAPIVersion, MQTTErrorCode
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties
from paho.mqtt.reasoncodes import ReasonCode

from app.jsontypes import JsonObject
from app.publish.settings import PublishSettings
from app.publish.sink import Batch, SinkError
from app.services.lifecycle.subject import AnySubject

if TYPE_CHECKING:
    from app.publish.commands import Reply, Workers

log = logging.getLogger(__name__)

#: Seconds a batch may wait for its PUBACKs while connected before it is tried again.
ACK_TIMEOUT_S = 10.0
#: Seconds a closing sink waits for paho's network thread to end (SIGTERM: exit within 1 s).
STOP_WAIT_S = 0.2
#: Seconds a closing sink waits for the broker to acknowledge its `offline` (a broker that
#: answers does in milliseconds; a hung one must not hold up the exit).
OFFLINE_WAIT_S = 0.3
KEEPALIVE_S = 30


@dataclass(frozen=True, slots=True)
class BrokerUrl:
    """TCPCAL_MQTT_URL taken apart."""

    host: str
    port: int
    tls: bool
    username: str | None
    password: str | None

    @property
    def where(self) -> str:
        """host:port, for messages (never the password)."""
        return f"{'mqtts' if self.tls else 'mqtt'}://{self.host}:{self.port}"


def parse_url(url: str) -> BrokerUrl:
    """`mqtt://user:pass@host:port` or `mqtts://...`; SinkError saying what is wrong."""
    hint = "give TCPCAL_MQTT_URL as mqtt://user:pass@host:1883 or mqtts://host:8883"
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError as exc:
        raise SinkError(f"TCPCAL_MQTT_URL is malformed ({exc}): {hint}") from None
    if parts.scheme not in ("mqtt", "mqtts"):
        raise SinkError(f"TCPCAL_MQTT_URL scheme {parts.scheme!r} is not mqtt or mqtts: {hint}")
    if not parts.hostname:
        raise SinkError(f"TCPCAL_MQTT_URL names no host: {hint}")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise SinkError(f"TCPCAL_MQTT_URL has a path or query, which MQTT has no use for: {hint}")
    tls = parts.scheme == "mqtts"
    return BrokerUrl(
        host=parts.hostname,
        port=port or (8883 if tls else 1883),
        tls=tls,
        username=None if parts.username is None else unquote(parts.username),
        password=None if parts.password is None else unquote(parts.password),
    )


def check_prefix(prefix: str) -> str:
    """A topic prefix without wildcards or empty levels at its ends."""
    if not prefix or prefix.startswith("/") or prefix.endswith("/"):
        raise SinkError(
            f"TCPCAL_MQTT_PREFIX {prefix!r} must be non-empty, without a leading or "
            "trailing '/': e.g. tcpcal or plant1/tcpcal"
        )
    if any(c in prefix for c in "+#\0"):
        raise SinkError(f"TCPCAL_MQTT_PREFIX {prefix!r} may not contain + # or NUL")
    return prefix


def state_topic(prefix: str, subject: AnySubject, subject_id: str) -> str:
    """The retained topic of a subject's active version (a tool's TCP:
    {prefix}/tools/{tool_id}/tcp), named by the subject's declaration."""
    return f"{prefix}/{subject.plural}/{subject_id}/{subject.leaf}"


def authorization_of(properties: Properties | None) -> str | None:
    """The `authorization` user property of an MQTT 5 message (None: absent)."""
    pairs = getattr(properties, "UserProperty", None) or []
    return next((str(v) for k, v in pairs if str(k).lower() == "authorization"), None)


def payload_of(document: JsonObject | None) -> bytes:
    """A retained tool message: the document as compact JSON, or empty (clears the topic)."""
    return b"" if document is None else json.dumps(document, separators=(",", ":")).encode()


class MqttSink:
    """The outbox on an MQTT broker (see the module's docstring)."""

    name = "mqtt"

    def __init__(
        self,
        broker: BrokerUrl,
        prefix: str,
        *,
        ca_file: str | None = None,
        connect_timeout_s: float = 5.0,
        commands: bool = False,
    ) -> None:
        self.broker = broker
        self.prefix = check_prefix(prefix)
        self.events_topic = f"{prefix}/events"
        self.status_topic = f"{prefix}/status"
        self._ca_file = ca_file
        self._connect_timeout_s = connect_timeout_s
        self._connected = threading.Event()
        self._connection = 0
        self._refused: str | None = None
        self._stopping = threading.Event()
        self._closing = False
        self._commands = commands
        #: the command workers, started by open() (imported then: the services are heavy)
        self._workers: Workers | None = None
        self._client = self._make_client()

    @classmethod
    def from_settings(cls, settings: PublishSettings) -> MqttSink:
        """The sink TCPCAL_MQTT_* describe (SinkError when malformed)."""
        assert settings.mqtt_url is not None
        return cls(
            parse_url(settings.mqtt_url),
            settings.mqtt_prefix,
            ca_file=settings.mqtt_ca_file,
            connect_timeout_s=settings.mqtt_connect_timeout_s,
            commands=settings.mqtt_commands,
        )

    def _make_client(self) -> mqtt.Client:
        client = mqtt.Client(  # MQTT 5 has no clean_session: its session expires at once
            callback_api_version=CallbackAPIVersion.VERSION2,
            client_id=f"tcpcal-publisher-{self.prefix}",
            clean_session=None if self._commands else True,
            protocol=mqtt.MQTTv5 if self._commands else mqtt.MQTTv311,
        )
        if self.broker.username is not None:
            client.username_pw_set(self.broker.username, self.broker.password)
        if self.broker.tls:
            client.tls_set(ca_certs=self._ca_file)
        client.will_set(self.status_topic, b"offline", qos=1, retain=True)
        client.reconnect_delay_set(min_delay=1, max_delay=30)
        client.max_inflight_messages_set(100)
        client.connect_timeout = self._connect_timeout_s
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        return client

    # ---- paho's network thread -------------------------------------------------------
    def _on_connect(
        self,
        client: mqtt.Client,
        _userdata: object,
        _flags: ConnectFlags,
        reason: ReasonCode,
        _properties: Properties | None,
    ) -> None:
        if reason.is_failure:
            self._refused = str(reason)
            log.error("broker %s refused the connection: %s", self.broker.where, reason)
            return
        self._refused = None
        if self._closing:  # a reconnection that completed as the sink closed: not online
            client.disconnect()
            return
        client.publish(self.status_topic, b"online", qos=1, retain=True)
        if self._commands:  # a clean session forgets it: made again at every connection
            from app.publish.commands import COMMANDS, recheck_topic

            client.subscribe([(recheck_topic(self.prefix, c), 1) for c in COMMANDS])
        self._connection += 1
        self._connected.set()
        log.info("connected to %s", self.broker.where)

    def _on_disconnect(
        self,
        _client: mqtt.Client,
        _userdata: object,
        _flags: DisconnectFlags,
        reason: ReasonCode,
        _properties: Properties | None,
    ) -> None:
        self._connected.clear()
        if not self._closing:
            log.warning("disconnected from %s (%s): reconnecting", self.broker.where, reason)

    def _on_message(
        self, _client: mqtt.Client, _userdata: object, message: mqtt.MQTTMessage
    ) -> None:
        """A command: handed to the workers (paho's thread must not wait for a controller).
        A retained one is stale (it was sent before this connection, perhaps long ago):
        ignored, so that a reconnection never repeats a re-check."""
        if self._workers is None:
            return
        if message.retain:
            log.warning("ignored a retained command on %s: send commands unretained", message.topic)
            return
        from app.publish.commands import command_of

        command = command_of(self.prefix, message.topic)
        self._workers.submit(bytes(message.payload), authorization_of(message.properties), command)

    def _reply(self, reply: Reply) -> None:
        """Publish a command's answer (a worker thread; paho's publish is thread-safe)."""
        properties = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
        properties.ContentType = reply.content_type
        # the HTTP status, and whether this is the first answer again (Idempotent-Replayed)
        said = [("status", str(reply.status))] + ([("replayed", "true")] if reply.replayed else [])
        properties.UserProperty = said
        self._client.publish(reply.topic, reply.payload, qos=1, properties=properties)

    # ---- the Sink protocol ---------------------------------------------------------------
    def open(self, stopping: threading.Event) -> None:
        """Connect, or SinkError: unreachable broker, refused credentials, TLS failure.
        Returns unconnected when `stopping` is set meanwhile (the runner then stops)."""
        self._stopping = stopping
        if self._commands:
            from app.publish.commands import Workers

            self._workers = Workers(self.prefix, self._reply)
            self._workers.start()
        failure = self._first_connect(stopping)
        if stopping.is_set():
            return
        if failure is not None:  # refused, unknown host, timeout, TLS
            raise SinkError(
                f"cannot reach the MQTT broker at {self.broker.where}: {failure}; check "
                "TCPCAL_MQTT_URL and that the broker runs"
            )
        self._client.loop_start()
        deadline = time.monotonic() + self._connect_timeout_s
        while not self._connected.is_set() and self._refused is None:
            if stopping.is_set():
                return
            if time.monotonic() > deadline:
                self._give_up()
                raise SinkError(
                    f"the MQTT broker at {self.broker.where} did not answer the connection "
                    f"within {self._connect_timeout_s:g} s"
                )
            self._connected.wait(0.05)
        if self._refused is not None:
            self._give_up()
            raise SinkError(
                f"the MQTT broker at {self.broker.where} refused the connection: "
                f"{self._refused}; check the user name and password in TCPCAL_MQTT_URL"
            )

    def _first_connect(self, stopping: threading.Event) -> OSError | None:
        """paho's connect (TCP, and TLS's handshake) in a thread of its own, so that SIGTERM
        is not kept waiting by a host that does not answer (up to the connect timeout): the
        error, or None once connected or when `stopping` was set meanwhile (the thread is
        left to end by itself)."""
        failure: list[OSError] = []

        def connect() -> None:
            try:
                self._client.connect(self.broker.host, self.broker.port, keepalive=KEEPALIVE_S)
            except OSError as exc:  # ssl.SSLError is an OSError
                failure.append(exc)

        thread = threading.Thread(target=connect, name="mqtt-connect", daemon=True)
        thread.start()
        while thread.is_alive() and not stopping.is_set():
            thread.join(0.05)
        return failure[0] if failure and not stopping.is_set() else None

    def _give_up(self) -> None:
        """Disconnect and stop paho's network thread, waiting for it at most
        STOP_WAIT_S: while it waits to reconnect (a sleep of up to 1 s at a time) or for a
        TCP handshake (up to the connect timeout) it cannot be interrupted, and a stopping
        publisher does not wait for it (a daemon thread: it ends with the process; having
        been told to disconnect, it connects no more)."""
        self._closing = True
        self._client.disconnect()
        stopper = threading.Thread(target=self._client.loop_stop, name="mqtt-stop", daemon=True)
        stopper.start()
        stopper.join(STOP_WAIT_S)

    def connection_id(self) -> int:
        """Changes at every (re)connection."""
        return self._connection

    def deliver(self, batch: Batch) -> bool:
        """Publish the batch; True once the broker acknowledged every message of it."""
        if not self._connected.is_set():
            return False
        infos: list[mqtt.MQTTMessageInfo] = []
        for message in batch.messages:
            body = json.dumps(message.event, separators=(",", ":")).encode()
            infos.append(self._client.publish(self.events_topic, body, qos=1))
        for state in batch.states:
            topic = state_topic(self.prefix, state.subject, state.subject_id)
            infos.append(
                self._client.publish(topic, payload_of(state.document), qos=1, retain=True)
            )
        if any(info.rc != MQTTErrorCode.MQTT_ERR_SUCCESS for info in infos):
            return False
        return self._acknowledged(infos)

    def _acknowledged(self, infos: list[mqtt.MQTTMessageInfo]) -> bool:
        """Wait for every PUBACK; False when the connection drops, the broker is silent for
        ACK_TIMEOUT_S, or the publisher is stopping."""
        deadline = time.monotonic() + ACK_TIMEOUT_S
        for info in infos:
            while not info.is_published():
                if (
                    not self._connected.is_set()
                    or self._stopping.is_set()
                    or time.monotonic() > deadline
                ):
                    return False
                try:
                    info.wait_for_publish(0.1)
                except (RuntimeError, ValueError):
                    return False
        return True

    def close(self) -> None:
        """Say `offline` (a clean DISCONNECT sends no will) and disconnect."""
        if self._workers is not None:
            self._workers.stop()
        if self._connected.is_set():
            info = self._client.publish(self.status_topic, b"offline", qos=1, retain=True)
            with contextlib.suppress(RuntimeError, ValueError):
                info.wait_for_publish(OFFLINE_WAIT_S)
        self._give_up()
