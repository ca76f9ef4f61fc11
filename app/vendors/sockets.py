"""Blocking TCP I/O under one deadline, for the socket-based connectors (kuka_kvp, fanuc_rmi).

Every wait (connect, send, receive) gets what is left of the operation's `Deadline`, so a
controller that accepts the connection and never answers fails the operation in
``timeout_s``, however many reads it would have taken. OS errors become
`ControllerUnreachable` naming the host, port and reason; a stall before the controller sent
a byte under the deadline (`Deadline.answered`) is `ControllerSilent`: something accepted the
connection, perhaps not speaking the protocol tried.
"""

from __future__ import annotations

import contextlib
import socket

from app.vendors.connector import ControllerSilent, ControllerUnreachable, Deadline


def open_connection(host: str, port: int, deadline: Deadline) -> socket.socket:
    """A TCP connection to host:port within the deadline, or ControllerUnreachable."""
    try:
        sock = socket.create_connection((host, port), timeout=deadline.remaining())
    except TimeoutError as err:
        raise ControllerUnreachable(
            f"{host}:{port} did not accept a connection within {deadline.timeout_s:g} s"
        ) from err
    except OSError as err:
        raise ControllerUnreachable(f"cannot connect to {host}:{port}: {_reason(err)}") from err
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def send_all(sock: socket.socket, data: bytes, deadline: Deadline, *, peer: str) -> None:
    """Send every byte before the deadline, or ControllerUnreachable."""
    try:
        sock.settimeout(deadline.remaining())
        sock.sendall(data)
    except TimeoutError as err:
        raise _stalled(peer, deadline) from err
    except OSError as err:
        raise ControllerUnreachable(f"{peer}: the connection failed: {_reason(err)}") from err


def recv_some(sock: socket.socket, deadline: Deadline, *, peer: str) -> bytes:
    """The next bytes the peer sends (at least one), or ControllerUnreachable."""
    try:
        sock.settimeout(deadline.remaining())
        chunk = sock.recv(65536)
    except TimeoutError as err:
        raise _stalled(peer, deadline) from err
    except OSError as err:
        raise ControllerUnreachable(f"{peer}: the connection failed: {_reason(err)}") from err
    if not chunk:
        raise ControllerUnreachable(f"{peer} closed the connection")
    deadline.answered = True
    return chunk


def recv_exactly(
    sock: socket.socket, size: int, buffer: bytearray, deadline: Deadline, *, peer: str
) -> bytes:
    """`size` bytes from `buffer` topped up from the socket; the rest stays in `buffer`."""
    while len(buffer) < size:
        buffer.extend(recv_some(sock, deadline, peer=peer))
    data = bytes(buffer[:size])
    del buffer[:size]
    return data


def recv_until(
    sock: socket.socket,
    terminator: bytes,
    buffer: bytearray,
    deadline: Deadline,
    *,
    peer: str,
    limit: int = 1 << 20,
) -> bytes:
    """Bytes up to (without) `terminator`; what follows it stays in `buffer`."""
    while (end := buffer.find(terminator)) < 0:
        if len(buffer) > limit:
            raise ControllerUnreachable(f"{peer} sent {len(buffer)} bytes without a message end")
        buffer.extend(recv_some(sock, deadline, peer=peer))
    data = bytes(buffer[:end])
    del buffer[: end + len(terminator)]
    return data


def close_quietly(sock: socket.socket | None) -> None:
    """Close a socket, ignoring the errors of one already dead."""
    if sock is None:
        return
    with contextlib.suppress(OSError):
        sock.close()


def _stalled(peer: str, deadline: Deadline) -> ControllerUnreachable:
    """A stall of a controller that answered under this deadline, or of one that never did."""
    if deadline.answered:
        return ControllerUnreachable(f"{peer} did not answer within {deadline.timeout_s:g} s")
    return ControllerSilent(
        f"{peer} accepted the TCP connection and sent nothing within {deadline.timeout_s:g} s"
    )


def _reason(err: OSError) -> str:
    return err.strerror or type(err).__name__
