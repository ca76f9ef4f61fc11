"""A FANUC controller with option R912 Remote Motion Interface: UTOOL[1..10], UFRAME[1..9].

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
the teach pendant enabled RMIT-008.

The RMI_MOVE TP program (B-84184EN/03 section 2.3.1, p. 9-10): FRC_Initialize creates it and
runs it, and it holds program control until the session that made it sends FRC_Abort or
FRC_Disconnect (the NOTE on p. 11). A session whose connection closes without either leaves
it holding control: every later FRC_Initialize answers ErrorID 7015 MEMO-015 Program
already exists (the NOTE on p. 9), and FRC_Abort from another session answers RMIT-014 RMI
Command Fail, as an R-30iB answered (vertec-io/Fanuc_RMI_API probe/FINDINGS-7015.md, replies
captured from the controller; the manual suggests aborting, the controller did not let it).
Only the pendant clears it (`delete_rmi_move`). FRC_ReadUToolData / FRC_WriteUToolData need
no FRC_Initialize (section 2.3, p. 8-9: answered once FRC_Connect is accepted).

The fault hook (`Faults`) names requests by their packet: "FRC_Connect" on the connect port,
the command's name on the session port; `drop_at` names one at which the controller closes
the session's connection without an answer.

Frame values are held as the controller's REALs (32-bit floats) unless `single_precision`
is False. `set_tool` / `tool` are the operator at the pendant (SETUP > Frames).

Where the robot stands (B-84184EN/03 2.3.14 "Packet To Read Current Robot Cartesian
Position", manual page 18, and 2.3.15 "Packet To Read Current Robot Joint Angles", page 19;
both need only a connection, 2.3 page 8-9): FRC_ReadCartesianPosition answers ``TimeTag``,
``Configuration`` {UToolNumber, UFrameNumber, Front, Up, Left, Flip, Turn4, Turn5, Turn6}
and ``Position`` {X, Y, Z, W, P, R, Ext1, Ext2, Ext3}: the TCP of the active UTOOL n in the
active UFRAME m, so Position = inverse(UFRAME[m]) * flange * UTOOL[n] with the flange in
the robot's world frame and UFRAME 0 / UTOOL 0 the identity (the world, the faceplate);
W, P, R are fixed-axis angles, R = Rz(R) Ry(P) Rx(W). FRC_ReadJointAngles answers
``TimeTag`` and ``JointAngle`` {J1 .. J9} (deg). FRC_ReadUFrameData (2.3.8, page 15)
answers ``FrameNumber`` and ``Frame`` {X, Y, Z, W, P, R} of UFRAME[FrameNumber]. Each takes
an optional ``Group`` (group 1 without it); another group answers RMIT-039 Invalid Group
Number (this controller has one group). The manual gives no range for FrameNumber: this one
has the 9 user frames FRC_GetStatus calls NumberUFrame (2.3.7), and another number answers
RMIT-003 Invalid UFrame Number (Appendix A.1). This module computes Position with its own
numpy and scipy from a flange the test jogs (`set_flange`, `jog_flange`), the user frames
the operator enters (`set_uframe`) and the numbers selected (`select`); the Configuration
bits are the test's to set (`configuration`), not computed from joints. `moving_per_read` makes the
robot move: each pose read finds the flange that many mm further along world x and J1 that
many degrees further.

User frames over RMI: FRC_WriteUFrameData (2.3.9 "Packet To Set User Frame Data", manual
pages 15-16) takes ``FrameNumber``, ``Frame`` {X, Y, Z, W, P, R} and an optional ``Group``
and answers ``ErrorID`` and ``Group``; it needs only a connection (2.3, page 9). The frame
table (`uframes`, number -> {X..R}) is apart from the tool table (`tools`): a frame write
changes that one UFRAME and nothing else. A number outside 1-9 answers RMIT-003 Invalid
UFrame Number, another group RMIT-039, a Frame missing one of X..R or not finite RMIT-023
Invalid Position Data (as the UTOOL write). "The Remote Motion Interface rejects this packet
if the robot is in motion when it receives this packet" (2.3.9, page 16): while `in_motion`
(or `moving_per_read`) the write is refused and the frame kept; the manual names no code for
it, and this controller answers RMIT-014 RMI Command Fail (Appendix A.1). FRC_GetUFrameUTool
(2.3.17 "Packet To Get Current User/Tool Frame Number", page 20) answers ``UFrameNumber`` and
``UToolNumber``, the numbers selected (the manual prints the return packet's name as
"FRC_GetUFrameUtool"; this controller echoes the command's name, as for every other packet);
FRC_SetUFrameUTool (2.3.6, page 13) selects them (a frame outside 0-9 answers RMIT-003, a
tool outside 0-10 RMIT-002). The fault hook names a frame write "FRC_WriteUFrameData":
"before" leaves the old frame, "after" holds the new one and answers nothing.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator
from typing import TypeGuard

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from tests.controllers.simbase import TcpSimulator

SLOTS = range(1, 11)
UFRAMES = range(1, 10)
FRAME_KEYS = ("X", "Y", "Z", "W", "P", "R")
EXT_KEYS = ("Ext1", "Ext2", "Ext3")
JOINT_KEYS = tuple(f"J{i}" for i in range(1, 10))
CONFIGURATION_KEYS = ("Front", "Up", "Left", "Flip", "Turn4", "Turn5", "Turn6")
RMIT = 2556928
INVALID_UTOOL = RMIT + 2
INVALID_UFRAME = RMIT + 3
TP_ENABLED = RMIT + 8
INVALID_COMMAND = RMIT + 13
COMMAND_FAIL = RMIT + 14
INVALID_POSITION_DATA = RMIT + 23
ALREADY_CONNECTED = RMIT + 26
INVALID_GROUP = RMIT + 39
PROGRAM_EXISTS = 7015


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
        #: every command's answer on the session, as the line sent (without the CRLF)
        self.replies: list[str] = []
        self.session_open = False
        #: RMI_MOVE exists and holds program control (made by an FRC_Initialize)
        self.rmi_move_held = False
        #: the packet name at which the session's connection is closed without an answer
        self.drop_at: str | None = None
        self._data_lock = threading.Lock()
        # Where the robot stands: the flange in the world frame (4x4, mm), the joints, the
        # user frames, the UFRAME and UTOOL numbers selected (0: the world, the faceplate).
        self._flange: NDArray[np.float64] = np.eye(4)
        self._flange[:3, 3] = (1000.0, 0.0, 1000.0)
        self.joints: dict[str, float] = dict.fromkeys(JOINT_KEYS, 0.0)
        self.uframes: dict[int, dict[str, float]] = {
            m: dict.fromkeys(FRAME_KEYS, 0.0) for m in UFRAMES
        }
        self.active_uframe = 0
        self.active_utool = 1
        #: the arm's configuration as the pendant shows it (F/N, U/D, T/B, turns): not computed
        self.configuration: dict[str, int] = {
            "Front": 1,
            "Up": 1,
            "Left": 0,
            "Flip": 0,
            "Turn4": 0,
            "Turn5": 0,
            "Turn6": 0,
        }
        #: a moving robot: each pose read finds the flange this many mm further along world x
        #: and J1 this many degrees further
        self.moving_per_read = 0.0
        #: the robot is moving: FRC_WriteUFrameData is refused (2.3.9)
        self.in_motion = False
        #: seconds the controller takes over each command on the session (a slow one)
        self.reply_delay_s = 0.0
        self._started = time.monotonic()

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

    def set_uframe(
        self, number: int, x: float, y: float, z: float, w: float, p: float, r: float
    ) -> None:
        """SETUP > Frames > User Frame: UFRAME[number] in the world frame (mm, deg)."""
        if number not in UFRAMES:
            raise ValueError(f"user frame {number} is not one of 1-9")
        with self._data_lock:
            self.uframes[number] = {
                k: self._real(v) for k, v in zip(FRAME_KEYS, (x, y, z, w, p, r), strict=True)
            }

    def uframe(self, number: int) -> tuple[float, ...]:
        """X, Y, Z, W, P, R of UFRAME[number] as the controller holds them."""
        with self._data_lock:
            return tuple(self.uframes[number][k] for k in FRAME_KEYS)

    def select(self, *, uframe: int, utool: int) -> None:
        """The program's UFRAME_NUM and UTOOL_NUM (0: the world frame, the faceplate)."""
        if uframe != 0 and uframe not in UFRAMES:
            raise ValueError(f"user frame {uframe} is not one of 0-9")
        if utool != 0 and utool not in SLOTS:
            raise ValueError(f"user tool {utool} is not one of 0-10")
        with self._data_lock:
            self.active_uframe, self.active_utool = uframe, utool

    def set_flange(self, position_mm: tuple[float, ...], rotation: NDArray[np.float64]) -> None:
        """The robot jogged: its flange at `position_mm` with the 3x3 `rotation`, both in the
        world frame."""
        matrix = np.eye(4)
        matrix[:3, :3] = Rotation.from_matrix(rotation).as_matrix()
        matrix[:3, 3] = position_mm
        with self._data_lock:
            self._flange = matrix

    def jog_flange(self, x: float, y: float, z: float, w: float, p: float, r: float) -> None:
        """The flange at X, Y, Z (mm) and W, P, R (deg) in the world frame."""
        self.set_flange((x, y, z), _wpr_rotation((w, p, r)).as_matrix())

    def flange(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The flange's position (mm) and 3x3 rotation in the world frame."""
        with self._data_lock:
            return self._flange[:3, 3].copy(), self._flange[:3, :3].copy()

    def set_joints(self, *angles: float) -> None:
        """J1, J2, ... (deg)."""
        with self._data_lock:
            self.joints.update(zip(JOINT_KEYS, (float(v) for v in angles), strict=False))

    def position(self) -> dict[str, float]:
        """X, Y, Z, W, P, R of the active UTOOL in the active UFRAME, from the flange."""
        with self._data_lock:
            return self._position()

    def _position(self) -> dict[str, float]:
        tcp = self._flange
        if self.active_uframe:
            tcp = np.linalg.inv(_matrix(self.uframes[self.active_uframe])) @ tcp
        if self.active_utool:
            tcp = tcp @ _matrix(self.tools[self.active_utool])
        wpr = Rotation.from_matrix(tcp[:3, :3]).as_euler("xyz", degrees=True)
        values = (*tcp[:3, 3], *wpr)
        return {k: self._real(float(v)) for k, v in zip(FRAME_KEYS, values, strict=True)}

    def _move(self) -> None:
        if self.moving_per_read:
            self._flange[0, 3] += self.moving_per_read
            self.joints["J1"] += self.moving_per_read

    def delete_rmi_move(self) -> None:
        """The operator deletes the RMI_MOVE program on the pendant (what clears a program a
        dead session left holding control, per the captured replies)."""
        self.rmi_move_held = False

    def _real(self, value: float) -> float:
        return float(np.float32(value)) if self.single_precision else float(value)

    # --- the wire -----------------------------------------------------------------------

    def serve(self, conn: socket.socket) -> None:
        """The connect port: FRC_Connect -> PortNumber."""
        for packet in _packets(conn):
            name = packet.get("Communication")
            self.fault_at(str(name))  # "before" or "after": no answer either way
            if self.stalled:
                continue
            self.slow()
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
        #: this session's FRC_Initialize made RMI_MOVE (its to abort)
        session = {"initialized": False}
        try:
            for packet in _packets(conn):
                self.packets.append(packet)
                name = str(packet.get("Communication") or packet.get("Command"))
                if name == self.drop_at:
                    return  # the connection closes: the session dies without a goodbye
                if name == "FRC_Disconnect":
                    if session["initialized"]:
                        self.rmi_move_held = False  # p. 11: Abort or Disconnect ends it
                    if not self.stalled:
                        _send(conn, {"Communication": "FRC_Disconnect", "ErrorID": 0})
                    return
                stop = self.fault_at(name)
                if stop == "before":
                    continue
                reply = self._command(packet, session)
                self.slow()
                if stop == "after":
                    self.stalled = True
                if not self.stalled:  # stalled mid-session: reads on, answers nothing
                    self.replies.append(_send(conn, reply))
        finally:
            # RMI_MOVE stays as it is: a session that ends without FRC_Abort or
            # FRC_Disconnect leaves it holding program control.
            self.session_open = False

    def _command(self, packet: dict[str, object], session: dict[str, bool]) -> dict[str, object]:
        name = packet.get("Command")
        if name == "FRC_Initialize":
            if self.teach_pendant_enabled:
                return {"Command": name, "ErrorID": TP_ENABLED, "GroupMask": 1}
            if self.rmi_move_held:
                return {"Command": name, "ErrorID": PROGRAM_EXISTS, "GroupMask": 1}
            self.rmi_move_held = session["initialized"] = True
            return {"Command": name, "ErrorID": 0, "GroupMask": 1}
        if name == "FRC_Abort":
            if not session["initialized"]:  # nothing of this session's to abort
                return {"Command": name, "ErrorID": COMMAND_FAIL}
            self.rmi_move_held = session["initialized"] = False
            return {"Command": name, "ErrorID": 0}
        if name in ("FRC_ReadUToolData", "FRC_WriteUToolData"):
            return self._utool(str(name), packet)
        if name in ("FRC_WriteUFrameData", "FRC_GetUFrameUTool", "FRC_SetUFrameUTool"):
            return self._uframe_command(str(name), packet)
        if name in ("FRC_ReadCartesianPosition", "FRC_ReadJointAngles", "FRC_ReadUFrameData"):
            group = packet.get("Group", 1)
            if group != 1:
                return {"Command": name, "ErrorID": INVALID_GROUP, "Group": group}
            with self._data_lock:
                return {"Command": name, "ErrorID": 0, **self._pose_read(str(name), packet)}
        return {"Command": name, "ErrorID": INVALID_COMMAND}

    def _pose_read(self, name: str, packet: dict[str, object]) -> dict[str, object]:
        """What follows ErrorID in the answer to a pose read (2.3.14, 2.3.15, 2.3.8)."""
        if name == "FRC_ReadUFrameData":
            number = packet.get("FrameNumber")
            if not isinstance(number, int) or isinstance(number, bool) or number not in UFRAMES:
                return {"ErrorID": INVALID_UFRAME, "FrameNumber": number, "Group": 1}
            return {"FrameNumber": number, "Frame": dict(self.uframes[number]), "Group": 1}
        self._move()
        time_tag = int((time.monotonic() - self._started) * 1000)
        if name == "FRC_ReadJointAngles":
            joints = {k: self._real(v) for k, v in self.joints.items()}
            return {"TimeTag": time_tag, "JointAngle": joints, "Group": 1}
        configuration = {"UToolNumber": self.active_utool, "UFrameNumber": self.active_uframe}
        return {
            "TimeTag": time_tag,
            "Configuration": configuration | self.configuration,
            "Position": self._position() | dict.fromkeys(EXT_KEYS, 0.0),
            "Group": 1,
        }

    def _uframe_command(self, name: str, packet: dict[str, object]) -> dict[str, object]:
        """FRC_WriteUFrameData (2.3.9), FRC_GetUFrameUTool (2.3.17), FRC_SetUFrameUTool
        (2.3.6)."""
        group = packet.get("Group", 1)
        answer: dict[str, object] = {"Command": name, "ErrorID": 0}
        if group != 1:
            return answer | {"ErrorID": INVALID_GROUP, "Group": group}
        with self._data_lock:
            if name == "FRC_GetUFrameUTool":
                numbers = {"UFrameNumber": self.active_uframe, "UToolNumber": self.active_utool}
                return answer | numbers | {"Group": group}
            if name == "FRC_SetUFrameUTool":
                return answer | {"ErrorID": self._set_numbers(packet), "Group": group}
        number = packet.get("FrameNumber")
        if not _is_number(number) or number not in UFRAMES:
            return answer | {"ErrorID": INVALID_UFRAME, "Group": group}
        frame_in = packet.get("Frame")
        if not _is_frame(frame_in):
            return answer | {"ErrorID": INVALID_POSITION_DATA, "Group": group}
        if self.in_motion or self.moving_per_read:
            return answer | {"ErrorID": COMMAND_FAIL, "Group": group}
        self.set_uframe(number, *(float(frame_in[k]) for k in FRAME_KEYS))
        return answer | {"Group": group}

    def _set_numbers(self, packet: dict[str, object]) -> int:
        """Select UFrameNumber and UToolNumber: 0 or the ErrorID refusing them."""
        uframe, utool = packet.get("UFrameNumber"), packet.get("UToolNumber")
        if not _is_number(uframe) or (uframe != 0 and uframe not in UFRAMES):
            return INVALID_UFRAME
        if not _is_number(utool) or (utool != 0 and utool not in SLOTS):
            return INVALID_UTOOL
        self.active_uframe, self.active_utool = uframe, utool
        return 0

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


def _is_number(value: object) -> TypeGuard[int]:
    """A JSON integer (not a boolean)."""
    return isinstance(value, int) and not isinstance(value, bool)


def _is_frame(frame: object) -> TypeGuard[dict[str, float]]:
    """{X, Y, Z, W, P, R}, each a finite number."""
    return isinstance(frame, dict) and all(
        isinstance(frame.get(k), int | float) and np.isfinite(frame[k]) for k in FRAME_KEYS
    )


def _wpr_rotation(wpr: tuple[float, ...]) -> Rotation:
    """FANUC's W, P, R (deg): R = Rz(R) Ry(P) Rx(W), scipy's fixed-axis "xyz"."""
    return Rotation.from_euler("xyz", wpr, degrees=True)


def _matrix(frame: dict[str, float]) -> NDArray[np.float64]:
    """A frame {X, Y, Z, W, P, R} as a 4x4 matrix."""
    matrix = np.eye(4)
    matrix[:3, :3] = _wpr_rotation(tuple(frame[k] for k in ("W", "P", "R"))).as_matrix()
    matrix[:3, 3] = [frame[k] for k in ("X", "Y", "Z")]
    return matrix


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


def _send(conn: socket.socket, packet: dict[str, object]) -> str:
    """Send one packet; the line sent, without its CRLF."""
    line = json.dumps(packet)
    conn.sendall(line.encode("ascii") + b"\r\n")
    return line
