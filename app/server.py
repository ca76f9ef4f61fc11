"""Serving details uvicorn leaves to us.

With --workers > 1 uvicorn binds the listening socket itself as socket.socket(AF_INET),
whose proto is 0; asyncio only sets TCP_NODELAY on accepted sockets whose proto is
IPPROTO_TCP, so every keep-alive response waited ~40 ms on Nagle's algorithm and the
client's delayed ACK (measured: 44 ms per request with 2 workers, 1.6 ms with 1).
This protocol sets TCP_NODELAY itself on every connection.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket

from uvicorn.protocols.http.h11_impl import H11Protocol

#: What `tcpcal serve` passes to uvicorn as `http=`.
HTTP_PROTOCOL = "app.server:NoDelayH11Protocol"


class NoDelayH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with TCP_NODELAY set on each connection."""

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        sock = transport.get_extra_info("socket")
        if sock is not None and sock.family in (socket.AF_INET, socket.AF_INET6):
            with contextlib.suppress(OSError):  # not a TCP socket after all: nothing to tune
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        super().connection_made(transport)
