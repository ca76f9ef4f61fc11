"""What every socket simulator shares: a loopback listener on a free port, one thread per
connection, start/stop, and a stalled mode that accepts connections and never answers; and
what every simulator shares, a test's fault hook and slow answers (`Faults`)."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable
from typing import Literal, Self

#: Where a fault stops a controller at a request: before applying it, or right after.
Stop = Literal["before", "after"]


class Faults:
    """A test's fault hook. `fault`, when set, is asked about each request the controller is
    about to apply, named in the simulator's words ("write $TOOL_DATA[3]",
    "FRC_WriteUToolData", "POST /rw/rapid/..."), and answers where the controller goes
    silent: "before" (the request is not applied) or "after" (applied, then not answered),
    or None. Silent is `stalled` from then on, until the test clears it (the controller
    back). A fault fires once."""

    stalled: bool
    fault: Callable[[str], Stop | None] | None = None
    #: seconds each answer waits before it is sent (a slow controller)
    reply_delay_s: float = 0.0

    def slow(self) -> None:
        """Wait `reply_delay_s` before an answer."""
        if self.reply_delay_s:
            time.sleep(self.reply_delay_s)

    def fault_at(self, request: str) -> Stop | None:
        """Where the fault stops the controller at `request`; "before" sets `stalled` (the
        simulator sets it after applying for "after")."""
        stop = None if self.fault is None else self.fault(request)
        if stop is not None:
            self.fault = None
        if stop == "before":
            self.stalled = True
        return stop


def go_silent(moment: Stop, request: str, *, nth: int = 1) -> Callable[[str], Stop | None]:
    """A fault: the controller goes silent at the `nth` request named `request`."""
    seen = 0

    def fault(name: str) -> Stop | None:
        nonlocal seen
        seen += name == request
        return moment if name == request and seen == nth else None

    return fault


class TcpSimulator(Faults):
    """A TCP server on 127.0.0.1 (a free port) whose `serve` handles one connection."""

    name = "simulator"

    def __init__(self) -> None:
        self.host = "127.0.0.1"
        self.port = 0
        #: True: accept connections, read what comes, answer nothing (a hung controller).
        self.stalled = False
        self._listeners: list[socket.socket] = []
        self._connections: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._threads: list[threading.Thread] = []
        self.connections_accepted = 0
        #: False once `stop` began: a connection accepted after that is closed at once
        self._running = False

    def start(self) -> Self:
        """Listen on a free loopback port (the same one again after a `stop`)."""
        self._running = True
        self.port = self.add_listener(self.port, self.serve)
        return self

    def add_listener(self, port: int, handler: Callable[[socket.socket], None]) -> int:
        """Listen on `port` (0: a free one) and serve its connections with `handler`."""
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((self.host, port))
        listener.listen(16)
        self._listeners.append(listener)
        self._spawn(self._accept_loop, listener, handler)
        port_bound: int = listener.getsockname()[1]
        return port_bound

    def stop(self) -> None:
        """Close the listeners and every open connection (a controller switched off)."""
        with self._lock:
            self._running = False
        listeners, self._listeners = self._listeners, []
        for listener in listeners:
            _shutdown(listener)
        with self._lock:
            connections = list(self._connections)
            self._connections.clear()
        for conn in connections:
            _shutdown(conn)
        for thread in self._threads:
            thread.join(timeout=2)
        self._threads = [t for t in self._threads if t.is_alive()]

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # --- for subclasses ---------------------------------------------------------------------

    def serve(self, conn: socket.socket) -> None:
        """Speak the protocol on one accepted connection until it closes."""
        raise NotImplementedError

    def _spawn(self, target: Callable[..., None], *args: object) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True)
        thread.start()
        self._threads.append(thread)

    def _accept_loop(
        self, listener: socket.socket, handler: Callable[[socket.socket], None]
    ) -> None:
        while True:
            try:
                conn, _ = listener.accept()
            except OSError:
                return
            with self._lock:
                # A client's connect completes in the kernel's backlog, before accept():
                # one accepted while `stop` runs must be closed too, or it would be served.
                if not self._running:
                    _shutdown(conn)
                    return
                self._connections.add(conn)
                self.connections_accepted += 1
            self._spawn(self._serve_one, conn, handler)

    def _serve_one(self, conn: socket.socket, handler: Callable[[socket.socket], None]) -> None:
        try:
            if self.stalled:
                while conn.recv(65536):
                    pass
            else:
                handler(conn)
        except OSError:
            pass
        finally:
            with self._lock:
                self._connections.discard(conn)
            _shutdown(conn)


def _shutdown(sock: socket.socket) -> None:
    with contextlib.suppress(OSError):
        sock.shutdown(socket.SHUT_RDWR)
    sock.close()
