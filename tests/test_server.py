"""`tcpcal serve` sets TCP_NODELAY on every connection (uvicorn's multi-worker socket does not)."""

from __future__ import annotations

import asyncio
import socket
from typing import Any
from unittest.mock import MagicMock

from uvicorn.config import Config
from uvicorn.server import ServerState

from app.server import HTTP_PROTOCOL, NoDelayH11Protocol


def test_protocol_sets_nodelay_on_a_proto_zero_socket() -> None:
    # the kind of socket uvicorn's bind_socket() creates for --workers > 1
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        assert sock.proto == 0
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) == 0
        transport = MagicMock()
        extra: dict[str, Any] = {
            "socket": sock,
            "peername": ("127.0.0.1", 5000),
            "sockname": ("127.0.0.1", 8000),
        }
        transport.get_extra_info.side_effect = lambda name, default=None: extra.get(name, default)
        config = Config(app=lambda *a: None, http=HTTP_PROTOCOL)
        config.load()
        # A loop of its own: after any asyncio.run() in the same worker the main thread has
        # none, and the protocol would ask for one (RuntimeError under pytest-xdist).
        loop = asyncio.new_event_loop()
        try:
            protocol = NoDelayH11Protocol(
                config=config, server_state=ServerState(), app_state={}, _loop=loop
            )
            protocol.connection_made(transport)
        finally:
            loop.close()
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0


def test_serve_uses_the_protocol() -> None:
    import inspect

    from app import cli

    assert "http=HTTP_PROTOCOL" in inspect.getsource(cli.serve)
    assert f"{NoDelayH11Protocol.__module__}:{NoDelayH11Protocol.__name__}" == HTTP_PROTOCOL
