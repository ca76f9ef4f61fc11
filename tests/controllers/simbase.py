"""What every socket simulator shares: a loopback listener on a free port, one thread per
connection, start/stop, and a stalled mode that accepts connections and never answers."""

from __future__ import annotations

import contextlib
import socket
import threading
from typing import Self


class TcpSimulator:
    """A TCP server on 127.0.0.1 (a free port) whose `serve` handles one connection."""

    name = "simulator"

    def __init__(self) -> None:
        self.host = "127.0.0.1"
        self.port = 0
        #: True: accept connections, read what comes, answer nothing (a hung controller).
        self.stalled = False
        self._listener: socket.socket | None = None
        self._connections: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._threads: list[threading.Thread] = []
        self.connections_accepted = 0

    def start(self) -> Self:
        """Listen on a free loopback port (the same one again after a `stop`)."""
        self._listener = self._listen(self.port)
        self.port = self._listener.getsockname()[1]
        self._spawn(self._accept_loop, self._listener)
        return self

    def stop(self) -> None:
        """Close the listener and every open connection (a controller switched off)."""
        listener, self._listener = self._listener, None
        if listener is not None:
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

    def _listen(self, port: int) -> socket.socket:
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((self.host, port))
        listener.listen(16)
        return listener

    def _spawn(self, target: object, *args: object) -> None:
        thread = threading.Thread(target=target, args=args, daemon=True)  # type: ignore[arg-type]
        thread.start()
        self._threads.append(thread)

    def _accept_loop(self, listener: socket.socket) -> None:
        while True:
            try:
                conn, _ = listener.accept()
            except OSError:
                return
            with self._lock:
                self._connections.add(conn)
                self.connections_accepted += 1
            self._spawn(self._serve_one, conn)

    def _serve_one(self, conn: socket.socket) -> None:
        try:
            if self.stalled:
                while conn.recv(65536):
                    pass
            else:
                self.serve(conn)
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
