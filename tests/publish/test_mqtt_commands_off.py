"""MQTT commands are off unless TCPCAL_MQTT_COMMANDS=true (issue 41): a publisher started
without it never subscribes to `{prefix}/commands/recheck`, so no command a broker carries
(API keys in its user properties) reaches the service. The connection callback is driven
directly with a recording client: no broker, and no waiting for a reply that must not come."""

from __future__ import annotations

from typing import Any

import pytest
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.reasoncodes import ReasonCode

from app.publish.mqtt import MqttSink
from app.publish.settings import PublishSettings


class RecordingClient:
    """What the sink's on_connect asks of paho's client."""

    def __init__(self) -> None:
        self.subscribed: list[tuple[str, int]] = []
        self.published: list[str] = []

    def subscribe(self, topic: str | list[tuple[str, int]], qos: int = 0) -> None:
        """paho's subscribe: one topic and its QoS, or a list of (topic, QoS) in one go."""
        self.subscribed.extend([(topic, qos)] if isinstance(topic, str) else topic)

    def publish(self, topic: str, *_: Any, **__: Any) -> None:
        self.published.append(topic)

    def disconnect(self) -> None:  # pragma: no cover - only a closing sink calls it
        raise AssertionError("the sink is not closing")


def _subscriptions_at_connect(monkeypatch: pytest.MonkeyPatch, **env: str) -> list[tuple[str, int]]:
    monkeypatch.delenv("TCPCAL_MQTT_COMMANDS", raising=False)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setenv("TCPCAL_MQTT_URL", "mqtt://127.0.0.1:1883")
    monkeypatch.setenv("TCPCAL_MQTT_PREFIX", "cell4")
    sink = MqttSink.from_settings(PublishSettings())
    client = RecordingClient()
    success = ReasonCode(PacketTypes.CONNACK, "Success")
    sink._on_connect(client, None, None, success, None)  # type: ignore[arg-type]
    assert client.published == ["cell4/status"]  # connected: online, as any publisher
    return client.subscribed


def test_commands_are_off_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    assert _subscriptions_at_connect(monkeypatch) == []


@pytest.mark.parametrize("value", ["false", "0"])
def test_commands_stay_off_unless_set_true(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    assert _subscriptions_at_connect(monkeypatch, TCPCAL_MQTT_COMMANDS=value) == []


def test_commands_on_subscribe_to_the_recheck_topics(monkeypatch: pytest.MonkeyPatch) -> None:
    """A tool's re-check and a frame's (issue 49), in one SUBSCRIBE at QoS 1."""
    on = _subscriptions_at_connect(monkeypatch, TCPCAL_MQTT_COMMANDS="true")
    assert on == [("cell4/commands/recheck", 1), ("cell4/commands/recheck-frame", 1)]
