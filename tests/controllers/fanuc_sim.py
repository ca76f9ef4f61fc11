"""A FANUC controller with option R912 Remote Motion Interface, in memory: UTOOL[1..10].

Follows FANUC B-84184EN/03 *Remote Motion Interface Operator's Manual* (the copy in
vertec-io/Fanuc_RMI_API ``docs/RMI Operators Manual.pdf``): JSON packets ended by
``\\r\\n``; FRC_Connect on the connect port answers ``PortNumber`` (the session port,
here a second free loopback port) with ``MajorVersion``/``MinorVersion`` (2.2.1, Table 2.2.1,
manual page 6; the client fanuc-rmi reads ``Port`` instead, and the manual is followed);
FRC_ReadUToolData / FRC_WriteUToolData as 2.3.10 and 2.3.11 (pages 16-17); on the session
port FRC_Initialize, FRC_Abort, FRC_ReadUToolData / FRC_WriteUToolData (``ToolNumber``,
``Frame`` {X, Y, Z, W, P, R}, ``Group``) and FRC_Disconnect, each answered with its name and
``ErrorID`` (Appendix A: RMIT-nnn = 2556928 + nnn). One RMI client at a time: FRC_Connect
while a session is open answers RMIT-026 Robot is Already Connected; a session ends with
FRC_Disconnect or when its connection closes. A tool number outside 1-10 answers RMIT-002
Invalid UTool Number, an unknown command RMIT-013 Invalid RMI Command, FRC_Initialize with
the teach pendant enabled RMIT-008, FRC_Abort with RMI not running RMIT-009.

Frame values are held as the controller's REALs (32-bit floats) unless `single_precision`
is False. `set_tool` / `tool` are the operator at the pendant (SETUP > Frames).
"""

from __future__ import annotations

import json
import socket
import threading
from collections.abc import Iterator

import numpy as np

from tests.controllers.simbase import TcpSimulator

SLOTS = range(1, 11)
FRAME_KEYS = ("X", "Y", "Z", "W", "P", "R")
RMIT = 2556928
INVALID_UTOOL = RMIT + 2
TP_ENABLED = RMIT + 8
RMI_NOT_RUNNING = RMIT + 9
INVALID_COMMAND = RMIT + 13
INVALID_POSITION_DATA = RMIT + 23
ALREADY_CONNECTED = RMIT + 26


class FanucSimulator(TcpSimulator):
    """RMI on an in-memory FANUC controller with 10 user tools."""

    name = "FANUC RMI"

    def __init__(self, *, single_precision: bool = True) -> None:
        super().__init__()
        self.single_precision = single_precision
        self.session_port = 0
        #: the teach pendant's enable switch: FRC_Initialize is refused while it is on
        self.teach_pendant_enabled = False
        self.tools: dict[int, dict[str, float]] = {s: dict.fromkeys(FRAME_KEYS, 0.0) for s in SLOTS}
        self.packets: list[dict[str, object]] = []
        self.session_open = False
        self.rmi_running = False
        self._data_lock = threading.Lock()

    def start(self) -> FanucSimulator:
        super().start()
        self.session_port = self.add_listener(self.session_port, self.serve_session)
        return self

    # --- the pendant --------------------------------------------------------------------

    def set_tool(
        self, slot: int, x: float, y: float, z: float, w: float, p: float, r: float
    ) -> None:
        """What an operator enters in SETUP > Frames > Tool Frame (mm, deg)."""
        with self._data_lock:
            self.tools[slot] = {
                k: self._real(v) for k, v in zip(FRAME_KEYS, (x, y, z, w, p, r), strict=True)
            }

    def tool(self, slot: int) -> tuple[float, ...]:
        """X, Y, Z, W, P, R of UTOOL[slot] as the controller holds them."""
        with self._data_lock:
            return tuple(self.tools[slot][k] for k in FRAME_KEYS)

    def _real(self, value: float) -> float:
        return float(np.float32(value)) if self.single_precision else float(value)

    # --- the wire -----------------------------------------------------------------------

    def serve(self, conn: socket.socket) -> None:
        """The connect port: FRC_Connect -> PortNumber."""
        for packet in _packets(conn):
            name = packet.get("Communication")
            if name != "FRC_Connect":
                _send(conn, {"Communication": name, "ErrorID": INVALID_COMMAND})
            elif self.session_open:
                _send(conn, {"Communication": name, "ErrorID": ALREADY_CONNECTED})
            else:
                _send(
                    conn,
                    {
                        "Communication": name,
                        "ErrorID": 0,
                        "PortNumber": self.session_port,
                        "MajorVersion": 5,
                        "MinorVersion": 0,
                    },
                )

    def serve_session(self, conn: socket.socket) -> None:
        """The session port: commands until FRC_Disconnect or the connection closes."""
        self.session_open = True
        try:
            for packet in _packets(conn):
                self.packets.append(packet)
                if packet.get("Communication") == "FRC_Disconnect":
                    _send(conn, {"Communication": "FRC_Disconnect", "ErrorID": 0})
                    return
                stop = self.fault_at(str(packet.get("Command")))
                if stop == "before":
                    continue
                reply = self._command(packet)
                if stop == "after":
                    self.stalled = True
                if not self.stalled:  # stalled mid-session: reads on, answers nothing
                    _send(conn, reply)
        finally:
            self.session_open = False
            self.rmi_running = False

    def _command(self, packet: dict[str, object]) -> dict[str, object]:
        name = packet.get("Command")
        if name == "FRC_Initialize":
            if self.teach_pendant_enabled:
                return {"Command": name, "ErrorID": TP_ENABLED, "GroupMask": 1}
            self.rmi_running = True
            return {"Command": name, "ErrorID": 0, "GroupMask": 1}
        if name == "FRC_Abort":
            was_running, self.rmi_running = self.rmi_running, False
            return {"Command": name, "ErrorID": 0 if was_running else RMI_NOT_RUNNING}
        if name in ("FRC_ReadUToolData", "FRC_WriteUToolData"):
            return self._utool(str(name), packet)
        return {"Command": name, "ErrorID": INVALID_COMMAND}

    def _utool(self, name: str, packet: dict[str, object]) -> dict[str, object]:
        number = packet.get("ToolNumber")
        group = packet.get("Group", 1)
        if not isinstance(number, int) or isinstance(number, bool) or number not in SLOTS:
            return {"Command": name, "ErrorID": INVALID_UTOOL, "ToolNumber": number, "Group": group}
        if name == "FRC_ReadUToolData":
            frame = dict(zip(FRAME_KEYS, self.tool(number), strict=True))
            return {
                "Command": name,
                "ErrorID": 0,
                "ToolNumber": number,
                "Frame": frame,
                "Group": group,
            }
        frame_in = packet.get("Frame")
        if not isinstance(frame_in, dict) or not all(
            isinstance(frame_in.get(k), int | float) and np.isfinite(frame_in[k])
            for k in FRAME_KEYS
        ):
            return {"Command": name, "ErrorID": INVALID_POSITION_DATA, "Group": group}
        self.set_tool(number, *(float(frame_in[k]) for k in FRAME_KEYS))
        return {"Command": name, "ErrorID": 0, "Group": group}


def _packets(conn: socket.socket) -> Iterator[dict[str, object]]:
    """Each JSON packet the peer sends, until it closes (unreadable lines answered)."""
    buffer = b""
    while True:
        chunk = conn.recv(65536)
        if not chunk:
            return
        buffer += chunk
        while b"\r\n" in buffer:
            line, buffer = buffer.split(b"\r\n", 1)
            if not line.strip():
                continue
            try:
                packet = json.loads(line)
            except ValueError:
                _send(conn, {"ErrorID": INVALID_COMMAND})
                continue
            if isinstance(packet, dict):
                yield packet
            else:
                _send(conn, {"ErrorID": INVALID_COMMAND})


def _send(conn: socket.socket, packet: dict[str, object]) -> None:
    conn.sendall(json.dumps(packet).encode("ascii") + b"\r\n")
