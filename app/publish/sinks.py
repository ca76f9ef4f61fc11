"""The sinks `tcpcal publish` is configured for, built before anything heavy is imported: a
wrong configuration is reported in a fraction of a second, not after the outbox's services,
numpy and scipy have loaded (about 2 s). Each sink's module is imported only when configured."""

from __future__ import annotations

from app.publish.endpoint import parse_endpoint
from app.publish.settings import PublishSettings
from app.publish.sink import Sink, SinkError


def build_sinks(settings: PublishSettings) -> list[Sink]:
    """The sinks the configuration asks for; SinkError when it asks for none or one is
    malformed (checked before the lock is taken, so a typo fails at once)."""
    sinks: list[Sink] = []
    if settings.mqtt_url:
        from app.publish.mqtt import MqttSink

        sinks.append(MqttSink.from_settings(settings))
    if settings.opcua_endpoint:
        parse_endpoint(settings.opcua_endpoint)  # a typo fails before the OPC UA stack loads
        from app.publish.opcua_sink import opcua_sink

        sinks.append(
            opcua_sink(
                settings.opcua_endpoint,
                anonymous=settings.opcua_anonymous,
                certificate=settings.opcua_certificate,
                private_key=settings.opcua_private_key,
            )
        )
    if not sinks:
        raise SinkError(
            "nothing to publish to: set TCPCAL_MQTT_URL (e.g. mqtt://user:pass@broker:1883) "
            "and/or TCPCAL_OPCUA_ENDPOINT (e.g. opc.tcp://0.0.0.0:4840/tcpcal/)"
        )
    return sinks
