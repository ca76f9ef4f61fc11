"""The OPC UA endpoint of `tcpcal publish` (TCPCAL_OPCUA_ENDPOINT), checked without the OPC
UA stack: `tcpcal publish` reports a malformed endpoint before it imports asyncua and the
outbox's services (about 2 s of start-up), app.publish.opcua serves it."""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import urlsplit

from app.publish.sink import SinkError

DEFAULT_PORT = 4840


class OpcUaStartError(SinkError):
    """The OPC UA server cannot start (bad endpoint, port in use): the message says why."""


@dataclass(frozen=True)
class Endpoint:
    """A parsed `opc.tcp://host:port/path` endpoint."""

    url: str
    host: str
    port: int


def parse_endpoint(url: str) -> Endpoint:
    """Check an endpoint URL (`opc.tcp://host[:port][/path]`, port 1-65535, default 4840)."""
    try:
        parts = urlsplit(url.strip())
        port = parts.port
    except ValueError:  # urlsplit: a port that is not a number, or out of range
        raise _bad_endpoint(url, "the port must be a number from 1 to 65535") from None
    if parts.scheme != "opc.tcp":
        raise _bad_endpoint(url, "the scheme must be opc.tcp://")
    if not parts.hostname:
        raise _bad_endpoint(url, "it names no host (use 0.0.0.0 to listen on every interface)")
    if port == 0:
        raise _bad_endpoint(url, "the port must be a number from 1 to 65535")
    return Endpoint(url=url.strip(), host=parts.hostname, port=port or DEFAULT_PORT)


def _bad_endpoint(url: str, why: str) -> OpcUaStartError:
    return OpcUaStartError(
        f"TCPCAL_OPCUA_ENDPOINT={url!r} is not usable: {why}; "
        "expected e.g. opc.tcp://0.0.0.0:4840/tcpcal/"
    )
