"""The publisher's configuration (`tcpcal publish` only: the API never reads it)."""

from __future__ import annotations

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class PublishSettings(BaseSettings):
    """Every field can be set as TCPCAL_<NAME>."""

    model_config = SettingsConfigDict(env_prefix="TCPCAL_", extra="ignore")

    mqtt_url: str | None = Field(
        default=None,
        description="mqtt://user:pass@host:1883 or mqtts://... (TLS); unset: no MQTT",
    )
    mqtt_prefix: str = Field(default="tcpcal", description="topic prefix: {prefix}/tools/...")
    mqtt_ca_file: str | None = Field(
        default=None, description="CA bundle for mqtts:// (default: the system's)"
    )
    mqtt_connect_timeout_s: float = Field(default=5.0, gt=0)
    mqtt_commands: bool = Field(
        default=False,
        description="answer re-check commands on {prefix}/commands/recheck (MQTT 5; "
        "docs/publishing.md)",
    )
    opcua_endpoint: str | None = Field(
        default=None,
        description="opc.tcp://host:port/path the OPC UA server listens at, e.g. "
        "opc.tcp://0.0.0.0:4840/tcpcal/; unset: no OPC UA",
    )
    opcua_anonymous: bool = Field(
        default=False,
        description="let OPC UA clients in without a user name and API key (still read-only)",
    )
    opcua_certificate: str | None = Field(
        default=None,
        description="the OPC UA server's certificate file (PEM or DER); unset with "
        "opcua_private_key: a self-signed one is made at start-up",
    )
    opcua_private_key: str | None = Field(
        default=None, description="the private key of opcua_certificate (PEM or DER)"
    )
    publish_poll_s: float = Field(
        default=0.2, gt=0, le=1.0, description="how often an idle publisher reads the outbox"
    )
    publish_batch: int = Field(default=200, ge=1, le=5000)
    outbox_keep_s: float = Field(
        default=300.0, ge=0, description="delivered rows are pruned this long after delivery"
    )
