"""FANUC tool frames over the Remote Motion Interface (option R912).

Followed: FANUC *Remote Motion Interface Operator's Manual* B-84184EN (a copy in
vertec-io/Fanuc_RMI_API ``docs/``, whose RMI_COMMANDS_REFERENCE.md and tests give the
packets as real controllers send them): the communication packets (FRC_Connect on TCP
16001 answers ``PortNumber``, the port of the session; FRC_Disconnect), the command packets
(FRC_ReadUToolData, FRC_WriteUToolData with ``ToolNumber`` 1-10
and ``Frame`` {X, Y, Z mm, W, P, R deg}), and the ErrorID table of Appendix A.1 (RMIT-nnn
alarms are 2556928 + nnn). Every packet is one JSON object ended by ``\r\n``; every packet
sent is answered by one with the same ``Communication``/``Command`` name and an ``ErrorID``
(0: done). FRC_Terminate and FRC_SystemFault can arrive unasked. The client fanuc-rmi
(PyPI) reads the session port from ``Port``; the manual and captured replies say
``PortNumber``, which this module follows.

Where the robot stands (issue 39, contract v1.3): FRC_ReadCartesianPosition (2.3.14, manual
page 18) answers the TCP of the active UTOOL n in the active UFRAME m (``Position`` {X, Y, Z,
W, P, R, Ext1..3}) with the two numbers in its ``Configuration`` (UToolNumber,
UFrameNumber), so the numbers describe the same moment as the position; FRC_ReadUFrameData
(2.3.8, page 15) and FRC_ReadUToolData (2.3.10, page 16) then give UFRAME[m] and UTOOL[n]
(0 is the world frame, the faceplate: the identity, not read), and the flange in the
robot's world frame is UFRAME[m] * Position * inverse(UTOOL[n]). FRC_ReadJointAngles (2.3.15,
page 19) answers ``JointAngle`` {J1..J9}: J1..J6 are the arm's joints (J7..J9, extended
axes, stay in the readings). All four are commands that need only a connection (2.3, pages
8-9) and are sent one after the other, each answered before the next (2.3: "make sure the
previously sent command packet is returned"), within one deadline.

User frames (contract v1.4 "Frames at the controller"): FRC_WriteUFrameData (2.3.9 "Packet
To Set User Frame Data", pages 15-16: ``FrameNumber`` 1-9, ``Frame`` {X, Y, Z, W, P, R},
``Group``) writes UFRAME[n] and FRC_ReadUFrameData (2.3.8) reads it back; both need only a
connection (2.3, page 9). UFRAME[n] is in the robot's world frame, as tcpcal holds a frame; a
fixed tool is a user frame too (contract v1.4 "Frames"). The frame the robot moves in is the
active UFRAME: ``Configuration.UFrameNumber`` of the pose read's FRC_ReadCartesianPosition
(2.3.14), the number FRC_GetUFrameUTool (2.3.17) answers, taken from the read that already
carries it (one packet less a watcher round) with UFRAME[m] read as above.

W, P, R are fixed-axis X-Y-Z angles: R = Rz(R) Ry(P) Rx(W) (``fanuc_wpr`` in
app.kinematics.poses). RMI reads and writes only the frame of a UTOOL: the payload lives in
PAYLOAD schedules that RMI cannot write, so a FANUC tool is read with ``load`` None and
its load is not written.

A session runs FRC_Connect -> (session port) reads/writes -> FRC_Disconnect, under one
deadline of ``timeout_s`` from `connect` (FRC_Connect, the session's connection, each read
and write), and `close` sends FRC_Disconnect within `CLEANUP_S` more whatever happened
before, unless the controller has stopped answering (then waiting again would only stall;
closing the connection ends the session on the controller's side).

No FRC_Initialize, and so no FRC_Abort: B-84184EN/03 section 2.3 (p. 8-9) lists
FRC_ReadUToolData and FRC_WriteUToolData among the commands the controller answers "once the
FRC_Connect packet is accepted"; FRC_Initialize is for motion: it creates the RMI_MOVE TP
program and runs it (2.3.1, p. 9). A session that initialized and then died without
FRC_Abort or FRC_Disconnect leaves RMI_MOVE holding program control (2.3.1, p. 10: "even if
you manually abort the RMI_MOVE TP program through the teach pendant, the RMI still has
program control"; the NOTE on p. 11: "always end your RMI session with either an FRC_Abort or
FRC_Disconnect packet"), and every later FRC_Initialize answers ErrorID 7015 MEMO-015
Program already exists (the NOTE on p. 9). The manual suggests FRC_Abort and re-initializing;
replies captured from an R-30iB (vertec-io/Fanuc_RMI_API probe/FINDINGS-7015.md) show that
from a new session FRC_Abort answers RMIT-014 and FRC_Initialize 7015 again, whatever is
sent: only the pendant clears it. We follow the captured replies: a session that never
initializes leaves nothing behind when it dies and is not stopped by what another left, so
the next deploy after a dropped session succeeds. The refusals that need someone at the
pendant say what to do there (`REMEDIES`).
"""

from __future__ import annotations

import contextlib
import json
import socket
import time

import numpy as np

from app.jsontypes import JsonObject
from app.kinematics.frames import flange_from_tcp
from app.kinematics.poses import fanuc_wpr_from_quaternion_wxyz, quaternion_wxyz_from_fanuc_wpr
from app.vendors.connector import (
    CLEANUP_S,
    ClosingSession,
    ControllerError,
    ControllerProtocolError,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    Deadline,
    Frame,
    FrameTarget,
    LiveFrame,
    LiveTool,
    PoseReading,
    ToolTarget,
    finite_frame,
    write_sent,
)
from app.vendors.fanuc import RMI
from app.vendors.sockets import close_quietly, open_connection, recv_until, send_all
from app.vendors.tool import ToolData, finite_tool_data

FRAME_KEYS = ("X", "Y", "Z", "W", "P", "R")
#: The arm's joints in FRC_ReadJointAngles' JointAngle (J7..J9 are extended axes).
JOINT_KEYS = ("J1", "J2", "J3", "J4", "J5", "J6")
#: The faceplate, and the world frame: UTOOL 0 and UFRAME 0.
_IDENTITY = Frame((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))
RMIT_BASE = 2556928
#: B-84184EN Appendix A: the RMIT alarms an ErrorID stands for (ErrorID = 2556928 + n).
RMIT_MESSAGES: dict[int, str] = {
    1: "Internal System Error",
    2: "Invalid UTool Number",
    3: "Invalid UFrame Number",
    4: "Invalid Position Register",
    5: "Invalid Speed Override",
    6: "Cannot Execute TP program",
    7: "Controller Servo is Off",
    8: "Teach Pendant is Enabled",
    9: "RMI is Not Running",
    10: "TP Program is Not Paused",
    11: "Cannot Resume TP Program",
    12: "Cannot Reset Controller",
    13: "Invalid RMI Command",
    14: "RMI Command Fail",
    15: "Invalid Controller State",
    16: "Please Cycle Power",
    17: "Invalid Payload Schedule",
    18: "Invalid Motion Option",
    19: "Invalid Vision Register",
    20: "Invalid RMI Instruction",
    21: "Invalid Value",
    22: "Invalid Text String",
    23: "Invalid Position Data",
    24: "RMI is In HOLD State",
    25: "Remote Device Disconnected",
    26: "Robot is Already Connected",
    27: "Wait for Command Done",
    28: "Wait for Instruction Done",
    29: "Invalid sequence ID number",
    39: "Invalid Group Number",
    40: "Invalid Group Mask",
    43: "Robot in Single Step Mode",
}
#: MEMO alarms RMI reports with their bare number.
MEMO_MESSAGES: dict[int, str] = {
    7004: "MEMO-004 Specific program is in use",
    7015: "MEMO-015 Program already exists",
}
#: RMIT-026 Robot is Already Connected: another client's session holds RMI
ALREADY_CONNECTED = RMIT_BASE + 26
#: What to do about an ErrorID that needs someone at the controller (B-84184EN/03 and
#: the captured replies cited in the module's docstring).
REMEDIES: dict[int, str] = {
    7015: (
        "an RMI_MOVE program holds the controller (left by an RMI session that ended without "
        "FRC_Abort or FRC_Disconnect, or selected on the pendant): on the teach pendant press "
        "SELECT, choose a program other than RMI_MOVE and press ENTER (B-84184EN section "
        "2.3.1); if that does not clear it, delete the RMI_MOVE program on the pendant"
    ),
    7004: (
        "the RMI_MOVE program is in use: on the teach pendant press SELECT, choose a program "
        "other than RMI_MOVE and press ENTER (B-84184EN section 2.3.1)"
    ),
    ALREADY_CONNECTED: (
        "RMI serves one client at a time (B-84184EN section 2.1) and another one holds it: "
        "end that client's session; a session whose connection was lost is ended by the "
        "controller after $RMI_CFG.$DISCNT_TIM minutes without a packet (default 60, "
        "section 2.2.3)"
    ),
}
#: how long, and how often, FRC_Connect is asked again while RMIT-026 is the answer
_BUSY_GRACE_S = 1.0
_BUSY_RETRY_S = 0.1
_NAME_KEYS = {"Communication", "Command", "Instruction"}


def error_text(error_id: int) -> str:
    """ "RMIT-002 Invalid UTool Number (ErrorID 2556930)", as the pendant names the alarm."""
    n = error_id - RMIT_BASE
    if n in RMIT_MESSAGES:
        return f"RMIT-{n:03d} {RMIT_MESSAGES[n]} (ErrorID {error_id})"
    if error_id in MEMO_MESSAGES:
        return f"{MEMO_MESSAGES[error_id]} (ErrorID {error_id})"
    return f"ErrorID {error_id}"


def encode_packet(packet: JsonObject) -> bytes:
    """One RMI packet as sent: JSON with every float in plain decimals (six places, never an
    exponent: the manual's examples never show one), ended by CRLF."""
    return _json_text(packet).encode("ascii") + b"\r\n"


def _json_text(value: object) -> str:
    if isinstance(value, dict):
        items = (f"{json.dumps(str(k))}: {_json_text(v)}" for k, v in value.items())
        return "{" + ", ".join(items) + "}"
    if isinstance(value, float):
        if not np.isfinite(value):
            raise ValueError(f"{value} cannot be sent to the controller")
        text = f"{value:.6f}"
        return "0.000000" if text == "-0.000000" else text
    return json.dumps(value)


class FanucRmiConnector(ClosingSession):
    """One RMI session with a FANUC controller: read and write UTOOL frames."""

    protocol = "fanuc_rmi"

    def __init__(self, settings: ControllerSettings) -> None:
        self._settings = settings
        self._sock: socket.socket | None = None
        self._buffer = bytearray()
        #: set once the controller stopped answering: `close` then says no goodbye (it
        #: would only wait again) and the controller frees the session on its own
        self._dead = False
        self._peer = f"FANUC RMI at {settings.host}:{settings.port}"
        #: the whole session's time budget, from here: FRC_Connect, each read and write
        self._deadline = Deadline(settings.timeout_s)
        session_port = self._session_port(self._deadline)
        self._peer = f"FANUC RMI session at {settings.host}:{session_port}"
        self._sock = open_connection(settings.host, session_port, self._deadline)

    # --- the Connector interface -----------------------------------------------------------

    def describe(self, target: ToolTarget) -> str:
        """``UTOOL[3]``."""
        return RMI.describe(target)

    def read_tool(self, target: ToolTarget) -> ToolData:
        """The frame of UTOOL[slot] (no load: RMI does not serve payloads)."""
        RMI.check(target)
        assert target.slot is not None  # RMI.check: a slot-addressed protocol
        frame, _line = self._read_frame(
            "FRC_ReadUToolData", "ToolNumber", target.slot, self._deadline
        )
        return ToolData(position_mm=frame.position_mm, quaternion=frame.quaternion, load=None)

    def read_pose(self) -> PoseReading:
        """Where the robot stands: the flange in the robot's world frame (UFRAME[m] *
        Position * inverse(UTOOL[n]) for the active m and n), J1..J6, the tool it moves by
        (UTOOL n and its frame; UTOOL 0, the faceplate, has no number) and each reply line as
        the controller sent it, keyed by its command; all within one timeout."""
        deadline = self._deadline
        readings: dict[str, str] = {}
        cartesian, readings["FRC_ReadCartesianPosition"] = self._request_line(
            {"Command": "FRC_ReadCartesianPosition", "Group": 1}, deadline
        )
        joints, readings["FRC_ReadJointAngles"] = self._request_line(
            {"Command": "FRC_ReadJointAngles", "Group": 1}, deadline
        )
        configuration = self._member(cartesian, "Configuration", "FRC_ReadCartesianPosition")
        uframe = self._frame_number(configuration, "UFrameNumber")
        utool = self._frame_number(configuration, "UToolNumber")
        position = self._numbers(cartesian, "Position", FRAME_KEYS, "FRC_ReadCartesianPosition")
        base = tool = _IDENTITY
        if uframe:
            base, readings["FRC_ReadUFrameData"] = self._read_frame(
                "FRC_ReadUFrameData", "FrameNumber", uframe, deadline
            )
        if utool:
            tool, readings["FRC_ReadUToolData"] = self._read_frame(
                "FRC_ReadUToolData", "ToolNumber", utool, deadline
            )
        tcp = _wpr_frame(position)
        flange = flange_from_tcp(
            (tcp.position_mm, tcp.quaternion),
            tool=(tool.position_mm, tool.quaternion),
            base=(base.position_mm, base.quaternion),
        )
        return PoseReading(
            flange=Frame(*flange),
            joints_deg=self._numbers(joints, "JointAngle", JOINT_KEYS, "FRC_ReadJointAngles"),
            live_tool=LiveTool(number=utool or None, frame=tool),
            readings=readings,
            live_frame=LiveFrame(number=uframe or None, name=None, frame=base),
        )

    def describe_frame(self, target: FrameTarget) -> str:
        """``UFRAME[2]``."""
        return RMI.describe_frame(target)

    def read_frame(self, target: FrameTarget) -> Frame:
        """UFRAME[slot] (FRC_ReadUFrameData, group 1)."""
        RMI.describe_frame(target)
        assert target.slot is not None  # a frame-number-addressed protocol
        frame, _line = self._read_frame(
            "FRC_ReadUFrameData", "FrameNumber", target.slot, self._deadline
        )
        return frame

    def write_frame(self, target: FrameTarget, frame: Frame) -> None:
        """Write X, Y, Z, W, P, R into UFRAME[slot] (FRC_WriteUFrameData, group 1)."""
        RMI.describe_frame(target)
        finite_frame(frame)
        w, p, r = (float(v) for v in fanuc_wpr_from_quaternion_wxyz(np.asarray(frame.quaternion)))
        x, y, z = (float(v) for v in frame.position_mm)
        packet: JsonObject = {
            "Command": "FRC_WriteUFrameData",
            "FrameNumber": target.slot,
            "Frame": dict(zip(FRAME_KEYS, (x, y, z, w, p, r), strict=True)),
            "Group": 1,
        }
        try:
            with write_sent():
                self._request(packet, self._deadline)
        except ControllerRefused as err:
            if err.controller_message != error_text(RMIT_BASE + 14):
                raise
            raise ControllerRefused(
                f"the FANUC controller refused FRC_WriteUFrameData: {err.controller_message}",
                controller_message=err.controller_message,
                remedy=(
                    "RMI rejects a user frame write while the robot moves (B-84184EN 2.3.9): "
                    "deploy again when the robot stands still"
                ),
            ) from err

    def write_tool(self, target: ToolTarget, data: ToolData) -> None:
        """Write X, Y, Z, W, P, R into UTOOL[slot] (the load is not RMI's to write)."""
        RMI.check(target)
        finite_tool_data(data)
        w, p, r = (float(v) for v in fanuc_wpr_from_quaternion_wxyz(np.asarray(data.quaternion)))
        x, y, z = (float(v) for v in data.position_mm)
        frame = dict(zip(FRAME_KEYS, (x, y, z, w, p, r), strict=True))
        packet: JsonObject = {
            "Command": "FRC_WriteUToolData",
            "ToolNumber": target.slot,
            "Frame": frame,
            "Group": 1,
        }
        deadline = self._deadline
        # Once the packet is handed to the socket the controller may have set the frame,
        # whether or not its answer arrives.
        with write_sent():
            self._request(packet, deadline)

    def close(self) -> None:
        """FRC_Disconnect (errors ignored, within CLEANUP_S past the session's deadline),
        then close; never raises."""
        if self._sock is None:
            return
        if not self._dead:
            with contextlib.suppress(ControllerError):
                self._request(
                    {"Communication": "FRC_Disconnect"}, self._deadline.extended(CLEANUP_S)
                )
        close_quietly(self._sock)
        self._sock = None

    # --- the replies -----------------------------------------------------------------------

    def _read_frame(
        self, command: str, number_key: str, number: int, deadline: Deadline
    ) -> tuple[Frame, str]:
        """UFRAME[number] or UTOOL[number] (FRC_ReadUFrameData, FRC_ReadUToolData) and the
        reply line; ControllerProtocolError when the reply is about another number."""
        reply, line = self._request_line(
            {"Command": command, number_key: number, "Group": 1}, deadline
        )
        if reply.get(number_key) != number:
            raise ControllerProtocolError(
                f"{self._peer}: {command} for {number_key} {number} answered "
                f"{number_key} {reply.get(number_key)!r}"
            )
        return _wpr_frame(self._numbers(reply, "Frame", FRAME_KEYS, command)), line

    def _member(self, reply: JsonObject, key: str, command: str) -> JsonObject:
        member = reply.get(key)
        if not isinstance(member, dict):
            raise ControllerProtocolError(f"{self._peer}: {command} without a {key}")
        return member

    def _numbers(
        self, reply: JsonObject, key: str, names: tuple[str, ...], command: str
    ) -> tuple[float, ...]:
        """reply[key][name] for each name, finite numbers; ControllerProtocolError naming
        the first that is not."""
        member = self._member(reply, key, command)
        values = []
        for name in names:
            value = member.get(name)
            if not isinstance(value, int | float) or isinstance(value, bool):
                raise ControllerProtocolError(f"{self._peer}: {command} {key}.{name} is {value!r}")
            if not np.isfinite(value):
                raise ControllerProtocolError(
                    f"{self._peer}: {command} {key}.{name} is not finite: {value!r}"
                )
            values.append(float(value))
        return tuple(values)

    def _frame_number(self, configuration: JsonObject, key: str) -> int:
        """Configuration.UFrameNumber / UToolNumber: 0 (the world, the faceplate) or more."""
        number = configuration.get(key)
        if not isinstance(number, int) or isinstance(number, bool) or number < 0:
            raise ControllerProtocolError(
                f"{self._peer}: FRC_ReadCartesianPosition Configuration.{key} is {number!r}"
            )
        return number

    # --- the packets -----------------------------------------------------------------------

    def _session_port(self, deadline: Deadline) -> int:
        """FRC_Connect; asked again for up to `_BUSY_GRACE_S` while the controller answers
        RMIT-026: RMI serves one client and frees a session when it sees its connection
        close, which for a session that just failed (tcpcal's own, a moment ago) may not have
        happened yet."""
        grace = Deadline(min(_BUSY_GRACE_S, deadline.left()))
        while True:
            try:
                return self._connect_once(deadline)
            except ControllerRefused as err:
                if err.controller_message != error_text(ALREADY_CONNECTED):
                    raise
                if grace.left() < _BUSY_RETRY_S:
                    raise
                time.sleep(_BUSY_RETRY_S)

    def _connect_once(self, deadline: Deadline) -> int:
        sock = open_connection(self._settings.host, self._settings.port, deadline)
        try:
            reply, _line = self._exchange(
                sock, bytearray(), {"Communication": "FRC_Connect"}, deadline
            )
        finally:
            close_quietly(sock)
        port = reply.get("PortNumber")
        if not isinstance(port, int) or not 0 < port < 65536:
            raise ControllerProtocolError(f"{self._peer}: FRC_Connect answered port {port!r}")
        return port

    def _request(self, packet: JsonObject, deadline: Deadline) -> JsonObject:
        reply, _line = self._request_line(packet, deadline)
        return reply

    def _request_line(self, packet: JsonObject, deadline: Deadline) -> tuple[JsonObject, str]:
        """The reply to `packet` on the session, and its line as received."""
        if self._sock is None:
            raise ControllerUnreachable(f"{self._peer}: the session is closed")
        try:
            return self._exchange(self._sock, self._buffer, packet, deadline)
        except ControllerUnreachable:
            self._dead = True
            raise

    def _exchange(
        self, sock: socket.socket, buffer: bytearray, packet: JsonObject, deadline: Deadline
    ) -> tuple[JsonObject, str]:
        kind = "Communication" if "Communication" in packet else "Command"
        name = packet[kind]
        send_all(sock, encode_packet(packet), deadline, peer=self._peer)
        while True:
            reply, line = self._read_packet(sock, buffer, deadline)
            if reply.get("Communication") in ("FRC_Terminate", "FRC_SystemFault"):
                raise ControllerUnreachable(
                    f"{self._peer} ended the session ({reply['Communication']})"
                )
            if reply.get(kind) == name or not _NAME_KEYS & reply.keys():
                break  # ours, or an unnamed answer (what a controller sends to a bad packet)
            # an answer to something else (a late reply): not ours, keep reading
        error_id = reply.get("ErrorID", 0)
        if not isinstance(error_id, int):
            raise ControllerProtocolError(f"{self._peer}: {name} answered ErrorID {error_id!r}")
        if error_id != 0:
            words = error_text(error_id)
            raise ControllerRefused(
                f"the FANUC controller refused {name}: {words}",
                controller_message=words,
                remedy=REMEDIES.get(error_id),
            )
        return reply, line

    def _read_packet(
        self, sock: socket.socket, buffer: bytearray, deadline: Deadline
    ) -> tuple[JsonObject, str]:
        """The next packet and its line as received (without the CRLF)."""
        line = recv_until(sock, b"\r\n", buffer, deadline, peer=self._peer).strip()
        if not line:
            return {}, ""
        try:
            packet = json.loads(line)
            text = line.decode("utf-8")
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            raise ControllerProtocolError(f"{self._peer} sent {line[:80]!r}: not JSON") from err
        if not isinstance(packet, dict):
            raise ControllerProtocolError(f"{self._peer} sent {line[:80]!r}: not a JSON object")
        return packet, text


def _wpr_frame(values: tuple[float, ...]) -> Frame:
    """X, Y, Z, W, P, R (mm, deg) as a Frame."""
    q = quaternion_wxyz_from_fanuc_wpr(values[3:])
    return Frame(
        (values[0], values[1], values[2]), (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
    )
