"""Universal Robots (e-Series, PolyScope 5.5.1+; CB3 3.12.0+): the live TCP, read over RTDE
and written by a URScript program sent to the secondary interface.

Followed: UR's *Real-Time Data Exchange (RTDE) Guide* and UR's Python client
(UniversalRobots/RTDE_Python_Client_Library ``rtde/rtde.py``): on the RTDE port (30004) the
client asks for protocol 2 (``V``), reads the controller's version (``v``), sets up one output
recipe (``O``: a frequency and the variable names; the answer is the recipe id and each
variable's type, ``NOT_FOUND`` for one the controller does not serve) and starts (``S``);
data packages (``U``) then come at the recipe's frequency; text messages (``M``) may come
between them. Every package is ``>HB`` (size with the header, type) and big-endian values.
The recipe: ``actual_TCP_pose`` (the TCP in the base frame), ``tcp_offset`` (the active TCP in
the flange frame; served from PolyScope 3.12.0 / 5.5.1 though the guide omits it:
Universal_Robots_Client_Library PR #110 and ``doc/polyscope_compatibility.rst``),
``actual_q``, ``robot_mode``, ``safety_mode``, ``payload``, ``payload_cog``: poses are x, y, z
in m and a rotation vector in rad, joints rad, the centre of gravity m.

A write is a secondary program (the URScript manual, "Connecting to URControl": ``sec`` in
the first column, indented lines, ``end`` in the first column, sent as text to port 30002):
``set_tcp(p[x, y, z, rx, ry, rz])``, and ``set_payload(m, [cx, cy, cz])`` when the tool has a
load. A ``sec`` program runs beside the program that is running (a ``def`` one would replace
it: Universal_Robots_ROS2_Driver #783). The secondary interface answers nothing to a
program; the connector reads what it sends (its version message on connection, state and
robot messages: the layouts of the Client Library's ``tests/fake_primary_server.cpp``) and
watches ``tcp_offset`` over RTDE until it shows what was written. Refusals: before sending,
a robot that is not running or not in a normal or reduced safety mode (a protective stop)
cannot run a program, so nothing is sent (`ControllerRefused`, not written); after sending,
error code C210 (the interface is read-only: the robot is in local control, as the Client
Library's ``primary_client.cpp`` reads it), any error code of report level VIOLATION or
worse, a runtime exception, or ``tcp_offset`` unchanged while data keeps coming: the program
was not applied (`ControllerRefused` marked `write_sent`; the read after it shows the old TCP).

Scope: live. A script-set TCP holds until a program is played: the program starts with the
installation's TCP (UR's payload article; the ROS2 driver #783, "TCP set back to zero").
tcpcal does not change the installation; the reconcile rounds show what the robot moves by.
The URScript file (app.vendors.ur.file) is the stored way: a program that calls its
``tcpcal_<tool>()`` sets the TCP at every start.

Frames (contract v1.4: UR answers 501 /no-frame-writer): a UR frame is a feature of the
installation (a point, line or plane taught in PolyScope's Installation > Features and saved
with the installation file), and no remote interface writes or reads one: RTDE's outputs
(the guide's list) carry the TCP (``actual_TCP_pose``, ``tcp_offset``) and no feature, the
primary and secondary interfaces' robot state (the Client Library's package layouts:
joint, Cartesian info with the TCP and its offset, kinematics, configuration, masterboard,
tool data) carries none either, and a URScript program sent to the secondary interface runs
beside the running one and changes no installation. So `write_frame` and `read_frame` raise
`FrameWriterMissing` naming the URScript file a program loads instead (app.vendors.ur's
frame text, a pose ``p[x, y, z, rx, ry, rz]`` in m and rad), sending nothing, and the pose
read names no live frame (`UNREAD_FRAME`): the feature a program moves in is the program's
own (a ``pose_trans`` in its script), which nothing serves.

The flange (contract v1.3): ``actual_TCP_pose * inverse(tcp_offset)``, both from one data
package, so they describe the same moment; the live tool is ``tcp_offset`` (UR has no tool
numbers). A session keeps one deadline of ``timeout_s`` from `connect`; RTDE data is read
fresh for each read (what was buffered before the call is dropped).
"""

from __future__ import annotations

import math
import select
import socket
import struct
from dataclasses import dataclass

import numpy as np

from app.kinematics.frames import flange_from_tcp
from app.kinematics.poses import (
    matrix_from_quaternion_wxyz,
    matrix_from_rotvec,
    quaternion_wxyz_from_matrix,
    rotvec_from_matrix,
)
from app.vendors.connector import (
    UNREAD_FRAME,
    ClosingSession,
    ControllerProtocolError,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    Deadline,
    Frame,
    FramesByHand,
    FrameTarget,
    LiveTool,
    PoseReading,
    ToolTarget,
    write_sent,
)
from app.vendors.sockets import close_quietly, open_connection, recv_exactly, send_all
from app.vendors.tool import ToolData, ToolLoad, finite_tool_data
from app.vendors.ur import RTDE

#: Why tcpcal cannot deploy a frame to a UR, and what a person loads instead.
NO_FEATURE_INTERFACE = (
    "no remote interface of a UR controller writes or reads an installation feature: RTDE "
    "serves the TCP and no feature, the primary and secondary interfaces' robot state "
    "carries none, and a URScript program sent to the secondary interface changes no "
    "installation (a feature is taught in PolyScope, Installation > Features, and saved with "
    "the installation)"
)
FRAME_FILE = "the frame's URScript file (its pose p[x, y, z, rx, ry, rz], m and rad)"

# RTDE package types (the guide; rtde.py Command)
_VERSION = ord("V")
_URCONTROL = ord("v")
_TEXT = ord("M")
_DATA = ord("U")
_OUTPUTS = ord("O")
_START = ord("S")
#: The output recipe and the type each variable must have.
RECIPE: tuple[tuple[str, str], ...] = (
    ("timestamp", "DOUBLE"),
    ("actual_TCP_pose", "VECTOR6D"),
    ("tcp_offset", "VECTOR6D"),
    ("actual_q", "VECTOR6D"),
    ("robot_mode", "INT32"),
    ("safety_mode", "INT32"),
    ("payload", "DOUBLE"),
    ("payload_cog", "VECTOR3D"),
)
_FORMAT = ">B" + "d" + "6d" * 3 + "ii" + "d" + "3d"
#: 125 Hz: what every RTDE controller serves (the CB3's control loop; e-Series 500 Hz).
FREQUENCY_HZ = 125.0
#: robot_mode and safety_mode in words (ur_client_library datatypes.h; the RTDE guide).
ROBOT_MODES = {
    -1: "no controller",
    0: "disconnected",
    1: "confirm safety",
    2: "booting",
    3: "power off",
    4: "power on",
    5: "idle",
    6: "backdrive",
    7: "running",
    8: "updating firmware",
}
SAFETY_MODES = {
    1: "normal",
    2: "reduced",
    3: "protective stop",
    4: "recovery",
    5: "safeguard stop",
    6: "system emergency stop",
    7: "robot emergency stop",
    8: "violation",
    9: "fault",
    10: "validate joint id",
    11: "undefined safety mode",
    12: "automatic mode safeguard stop",
    13: "system three position enabling stop",
}
_RUNNING = 7
_PROGRAM_SAFETY = (1, 2)
# The secondary interface (fake_primary_server.cpp)
_ROBOT_MESSAGE = 20
_MESSAGE_TEXT = 0
_MESSAGE_ERROR_CODE = 6
_MESSAGE_RUNTIME_EXCEPTION = 10
_REPORT_VIOLATION = 3
_READ_ONLY = 210
_MAX_PACKAGE = 1 << 20
#: written and read back agree to these (m, rad): the decimals the program is written with
_SAME_M = 1e-8
_SAME_RAD = 1e-8
#: time kept back from the deadline for the read that follows a write that was not applied
_READ_RESERVE_S = 0.25
REMOTE_CONTROL = (
    "the robot is in local control, so its secondary interface is read-only: on the pendant "
    "switch to Remote Control (the icon top right; enable it once under Settings > System > "
    "Remote Control), then deploy again"
)
STOPPED = (
    "on the pendant release the stop (or power on and release the brakes) so that the robot "
    "is running in normal mode, then deploy again"
)


@dataclass(frozen=True)
class Sample:
    """One RTDE data package of the recipe."""

    timestamp: float
    tcp_pose: tuple[float, ...]
    tcp_offset: tuple[float, ...]
    joints_rad: tuple[float, ...]
    robot_mode: int
    safety_mode: int
    payload_kg: float
    payload_cog_m: tuple[float, ...]


def pose_frame(pose: tuple[float, ...]) -> Frame:
    """A UR pose (m, rotation vector rad) as a Frame (mm, quaternion w, x, y, z)."""
    q = quaternion_wxyz_from_matrix(matrix_from_rotvec(np.asarray(pose[3:6])))
    x, y, z = (v * 1000.0 for v in pose[:3])
    return Frame((x, y, z), (float(q[0]), float(q[1]), float(q[2]), float(q[3])))


def frame_pose(position_mm: tuple[float, ...], quaternion: tuple[float, ...]) -> tuple[float, ...]:
    """A frame (mm, quaternion w, x, y, z) as a UR pose (m, rotation vector rad)."""
    rotvec = rotvec_from_matrix(matrix_from_quaternion_wxyz(np.asarray(quaternion)))
    return (*(v / 1000.0 for v in position_mm), *(float(v) for v in rotvec))


def set_tcp_program(data: ToolData) -> str:
    """The secondary program that sets the live TCP (and payload with a load)."""
    pose = frame_pose(data.position_mm, data.quaternion)
    lines = ["sec tcpcal_set_tcp():", f"  set_tcp(p[{_numbers(pose)}])"]
    if data.load is not None:
        cog = tuple(v / 1000.0 for v in data.load.cog_or_origin)
        lines.append(f"  set_payload({_number(data.load.mass_kg)}, [{_numbers(cog)}])")
    return "\n".join([*lines, "end", ""])


def _number(value: float) -> str:
    text = f"{value:.10f}"
    return "0.0" if float(text) == 0 else text


def _numbers(values: tuple[float, ...]) -> str:
    return ", ".join(_number(v) for v in values)


def _same_pose(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    """Two poses within the written decimals, the rotations compared as rotations."""
    if max(abs(x - y) for x, y in zip(a[:3], b[:3], strict=True)) > _SAME_M:
        return False
    rotation = matrix_from_rotvec(np.asarray(a[3:6])).T @ matrix_from_rotvec(np.asarray(b[3:6]))
    angle = math.acos(max(-1.0, min(1.0, (float(np.trace(rotation)) - 1.0) / 2.0)))
    return angle <= _SAME_RAD * 10


class UrRtdeConnector(FramesByHand, ClosingSession):
    """One session with a UR controller: RTDE open from the start, the secondary interface
    opened for a write; frames by hand (the module's "Frames")."""

    frame_reason = NO_FEATURE_INTERFACE
    frame_file = FRAME_FILE

    protocol = "ur_rtde"

    def __init__(self, settings: ControllerSettings) -> None:
        self._settings = settings
        self._deadline = Deadline(settings.timeout_s)
        host = settings.host
        rtde_port, secondary_port = (RTDE.port_of(settings, s) for s in ("rtde", "secondary"))
        self._rtde_peer = f"UR RTDE at {host}:{rtde_port}"
        self._secondary_peer = f"UR secondary interface at {host}:{secondary_port}"
        self._secondary: socket.socket | None = None
        self._secondary_buffer = bytearray()
        self._buffer = bytearray()
        #: RTDE and secondary text messages seen in this session, in words
        self.messages: list[str] = []
        self.version: tuple[int, ...] = ()
        self._recipe_id = 0
        self._sock: socket.socket | None = open_connection(host, rtde_port, self._deadline)
        try:
            self._handshake()
        except BaseException:
            self.close()
            raise

    # --- the Connector interface -----------------------------------------------------------

    def describe(self, target: ToolTarget) -> str:
        """``tcp_offset``: every tool of a UR robot is written into its one live TCP."""
        return RTDE.describe(target)

    def read_tool(self, target: ToolTarget) -> ToolData:
        """The live TCP (``tcp_offset``) and, when one is set, the payload."""
        RTDE.check(target)
        sample = self._fresh()
        frame = pose_frame(sample.tcp_offset)
        load = None
        if sample.payload_kg > 0:
            cx, cy, cz = (v * 1000.0 for v in sample.payload_cog_m)
            load = ToolLoad(mass_kg=sample.payload_kg, cog_mm=(cx, cy, cz))
        return ToolData(position_mm=frame.position_mm, quaternion=frame.quaternion, load=load)

    def read_pose(self) -> PoseReading:
        """The flange (``actual_TCP_pose * inverse(tcp_offset)`` of one data package), the
        joints (``actual_q``) and the live tool (``tcp_offset``), with the values read."""
        sample = self._fresh()
        tcp = pose_frame(sample.tcp_pose)
        tool = pose_frame(sample.tcp_offset)
        flange = flange_from_tcp(
            (tcp.position_mm, tcp.quaternion), tool=(tool.position_mm, tool.quaternion)
        )
        return PoseReading(
            flange=Frame(*flange),
            joints_deg=tuple(math.degrees(v) for v in sample.joints_rad),
            live_tool=LiveTool(number=None, frame=tool),
            live_frame=UNREAD_FRAME,
            readings={
                "actual_TCP_pose": _printed(sample.tcp_pose),
                "tcp_offset": _printed(sample.tcp_offset),
                "actual_q": _printed(sample.joints_rad),
                "timestamp": repr(sample.timestamp),
            },
        )

    def describe_frame(self, target: FrameTarget) -> str:
        """``installation feature``."""
        return RTDE.describe_frame(target)

    def write_tool(self, target: ToolTarget, data: ToolData) -> None:
        """``set_tcp`` (and ``set_payload`` with a load) in a secondary program; returns once
        ``tcp_offset`` shows it. Refused before sending when the robot cannot run a program."""
        RTDE.check(target)
        finite_tool_data(data)
        program = set_tcp_program(data)
        self._check_can_run(self._fresh())
        self._open_secondary()
        assert self._secondary is not None
        pose = frame_pose(data.position_mm, data.quaternion)
        # Once the program is handed to the socket the controller may run it, whether or not
        # tcp_offset is seen to change.
        with write_sent():
            send_all(
                self._secondary, program.encode("ascii"), self._deadline, peer=self._secondary_peer
            )
            self._await_applied(pose, data.load)

    def close(self) -> None:
        """Close both connections (the controller ends an RTDE session whose connection
        closes); never raises."""
        close_quietly(self._secondary)
        self._secondary = None
        close_quietly(self._sock)
        self._sock = None

    # --- RTDE --------------------------------------------------------------------------------

    def _handshake(self) -> None:
        accepted = self._ask(_VERSION, struct.pack(">H", 2))
        if accepted[:1] != b"\x01":
            raise ControllerRefused(
                f"{self._rtde_peer} does not speak RTDE protocol 2",
                controller_message=f"protocol version 2 answered {accepted!r}",
                remedy="update the robot's software to PolyScope 5.5.1 or later (CB3: 3.12.0)",
            )
        answer = self._ask(_URCONTROL)
        if len(answer) != 16:
            raise ControllerProtocolError(f"{self._rtde_peer}: a version of {len(answer)} bytes")
        self.version = struct.unpack(">IIII", answer)
        names = ",".join(name for name, _ in RECIPE)
        answer = self._ask(_OUTPUTS, struct.pack(">d", FREQUENCY_HZ) + names.encode("ascii"))
        self._check_recipe(answer)
        if self._ask(_START)[:1] != b"\x01":
            raise ControllerRefused(
                f"{self._rtde_peer} did not start sending data",
                controller_message="; ".join(self.messages) or "RTDE start not accepted",
            )

    def _check_recipe(self, answer: bytes) -> None:
        if not answer:
            raise ControllerProtocolError(f"{self._rtde_peer}: an empty answer to the recipe")
        types = answer[1:].decode("ascii", "replace").split(",")
        missing = [
            name for (name, _), kind in zip(RECIPE, types, strict=False) if kind == "NOT_FOUND"
        ]
        if missing:
            version = ".".join(str(v) for v in self.version[:3])
            raise ControllerRefused(
                f"the UR controller (software {version}) does not serve {', '.join(missing)} "
                "over RTDE",
                controller_message=f"NOT_FOUND: {', '.join(missing)}",
                remedy="update the robot's software to PolyScope 5.5.1 or later (CB3: 3.12.0)",
            )
        expected = [kind for _, kind in RECIPE]
        if types != expected or answer[0] == 0:
            raise ControllerProtocolError(
                f"{self._rtde_peer}: the recipe was answered {answer[0]} {types}, not {expected}"
            )
        self._recipe_id = answer[0]

    def _ask(self, kind: int, payload: bytes = b"") -> bytes:
        """Send a request and return its answer's payload (text messages kept, data skipped)."""
        sock = self._rtde()
        send_all(
            sock,
            struct.pack(">HB", 3 + len(payload), kind) + payload,
            self._deadline,
            peer=self._rtde_peer,
        )
        while True:
            got, answer = self._package(self._deadline)
            if got == kind:
                return answer

    def _rtde(self) -> socket.socket:
        if self._sock is None:
            raise ControllerUnreachable(f"{self._rtde_peer}: the session is closed")
        return self._sock

    def _package(self, deadline: Deadline) -> tuple[int, bytes]:
        """The next complete RTDE package (text messages noted on the way)."""
        sock = self._rtde()
        while True:
            size, kind = struct.unpack(
                ">HB", recv_exactly(sock, 3, self._buffer, deadline, peer=self._rtde_peer)
            )
            if size < 3:
                raise ControllerProtocolError(f"{self._rtde_peer}: a package of size {size}")
            payload = recv_exactly(sock, size - 3, self._buffer, deadline, peer=self._rtde_peer)
            if kind != _TEXT:
                return kind, payload
            self.messages.append(_rtde_text(payload))

    def _fresh(self) -> Sample:
        """The first data package sent after this call."""
        partial = self._drain()
        sample = self._sample(self._deadline)
        return self._sample(self._deadline) if partial else sample

    def _drain(self) -> bool:
        """Read what has arrived and drop its data packages; True when part of one is left
        (it was sent before the call)."""
        self._buffer.extend(_available(self._rtde(), self._rtde_peer))
        while len(self._buffer) >= 3:
            size, kind = struct.unpack_from(">HB", self._buffer)
            if size < 3 or len(self._buffer) < size:
                break
            payload = bytes(self._buffer[3:size])
            del self._buffer[:size]
            if kind == _TEXT:
                self.messages.append(_rtde_text(payload))
        return bool(self._buffer)

    def _sample(self, deadline: Deadline) -> Sample:
        while True:
            kind, payload = self._package(deadline)
            if kind == _DATA:
                break
        if len(payload) != struct.calcsize(_FORMAT) or payload[0] != self._recipe_id:
            raise ControllerProtocolError(
                f"{self._rtde_peer}: a data package of {len(payload)} bytes for recipe "
                f"{payload[:1]!r}, not recipe {self._recipe_id}"
            )
        values = struct.unpack(_FORMAT, payload)[1:]
        if not all(math.isfinite(v) for v in values):
            raise ControllerProtocolError(
                f"{self._rtde_peer}: a value that is not finite: {values}"
            )
        return Sample(
            timestamp=values[0],
            tcp_pose=values[1:7],
            tcp_offset=values[7:13],
            joints_rad=values[13:19],
            robot_mode=int(values[19]),
            safety_mode=int(values[20]),
            payload_kg=values[21],
            payload_cog_m=values[22:25],
        )

    # --- the write ------------------------------------------------------------------------

    def _check_can_run(self, sample: Sample) -> None:
        if sample.robot_mode == _RUNNING and sample.safety_mode in _PROGRAM_SAFETY:
            return
        robot = ROBOT_MODES.get(sample.robot_mode, "unknown")
        safety = SAFETY_MODES.get(sample.safety_mode, "unknown")
        raise ControllerRefused(
            f"the UR robot cannot run a program now (robot mode {robot}, safety mode {safety}): "
            "nothing was sent",
            controller_message=(
                f"robot_mode {sample.robot_mode} ({robot}), safety_mode {sample.safety_mode} "
                f"({safety})"
            ),
            remedy=STOPPED,
        )

    def _open_secondary(self) -> None:
        """Connect to the secondary interface and read its first package (the version
        message a controller sends on connection): a silent one fails before the write."""
        port = RTDE.port_of(self._settings, "secondary")
        self._secondary = open_connection(self._settings.host, port, self._deadline)
        self._secondary_package(self._deadline)

    def _await_applied(self, pose: tuple[float, ...], load: ToolLoad | None) -> None:
        """Until tcp_offset (and the payload) show what was written. ControllerRefused when
        the secondary interface reports a refusal, or when tcp_offset still shows the old TCP
        while data keeps coming with only `_READ_RESERVE_S` left (kept for the read after it);
        ControllerUnreachable when the controller goes silent (it may have run it or not)."""
        reserve = min(_READ_RESERVE_S, self._deadline.timeout_s / 4)
        while True:
            self._poll_secondary()
            seen = self._sample(self._deadline)
            if _same_pose(seen.tcp_offset, pose) and _load_applied(seen, load):
                return
            if self._deadline.left() < reserve:
                raise self._not_applied(seen)

    def _not_applied(self, seen: Sample) -> ControllerRefused:
        said = "; ".join(self.messages) or "nothing"
        return ControllerRefused(
            f"the UR controller did not apply the program: tcp_offset still shows "
            f"{_printed(seen.tcp_offset)} after {self._deadline.timeout_s:g} s",
            controller_message=f"the controller said: {said}",
        )

    def _poll_secondary(self) -> None:
        """Read what the secondary interface sent; a refusal among it raises."""
        assert self._secondary is not None
        self._secondary_buffer.extend(_available(self._secondary, self._secondary_peer))
        while len(self._secondary_buffer) >= 5:
            size, _kind = struct.unpack_from(">iB", self._secondary_buffer)
            if size < 5 or size > _MAX_PACKAGE:
                raise ControllerProtocolError(f"{self._secondary_peer}: a package of size {size}")
            if len(self._secondary_buffer) < size:
                break
            package = bytes(self._secondary_buffer[:size])
            del self._secondary_buffer[:size]
            self._robot_message(package)

    def _secondary_package(self, deadline: Deadline) -> bytes:
        sock = self._secondary
        assert sock is not None
        head = recv_exactly(sock, 5, self._secondary_buffer, deadline, peer=self._secondary_peer)
        (size,) = struct.unpack_from(">i", head)
        if size < 5 or size > _MAX_PACKAGE:
            raise ControllerProtocolError(f"{self._secondary_peer}: a package of size {size}")
        body = recv_exactly(
            sock, size - 5, self._secondary_buffer, deadline, peer=self._secondary_peer
        )
        return head + body

    def _robot_message(self, package: bytes) -> None:
        """A refusal in a robot message raises ControllerRefused; text is noted."""
        if package[4] != _ROBOT_MESSAGE or len(package) < 15:
            return
        kind, body = package[14], package[15:]
        if kind == _MESSAGE_TEXT:
            self.messages.append(body.decode("utf-8", "replace"))
        elif kind == _MESSAGE_ERROR_CODE and len(body) >= 20:
            code, argument, level = struct.unpack_from(">iii", body)
            words = f"C{code}A{argument} {body[20:].decode('utf-8', 'replace')}".strip()
            self.messages.append(words)
            if code == _READ_ONLY or level >= _REPORT_VIOLATION:
                raise ControllerRefused(
                    f"the UR controller refused the program: {words}",
                    controller_message=words,
                    remedy=REMOTE_CONTROL if code == _READ_ONLY else None,
                )
        elif kind == _MESSAGE_RUNTIME_EXCEPTION and len(body) >= 8:
            line, column = struct.unpack_from(">II", body)
            words = f"line {line}, column {column}: {body[8:].decode('utf-8', 'replace')}"
            raise ControllerRefused(
                f"the UR controller stopped the program: {words}", controller_message=words
            )


def _available(sock: socket.socket, peer: str) -> bytes:
    """Every byte that has arrived, without waiting; ControllerUnreachable when the peer
    closed or the connection failed."""
    data = bytearray()
    try:
        while select.select([sock], [], [], 0)[0]:
            chunk = sock.recv(65536)
            if not chunk:
                raise ControllerUnreachable(f"{peer} closed the connection")
            data.extend(chunk)
    except OSError as err:
        raise ControllerUnreachable(f"{peer}: the connection failed: {err}") from err
    return bytes(data)


def _load_applied(sample: Sample, load: ToolLoad | None) -> bool:
    if load is None:
        return True
    cog = tuple(v / 1000.0 for v in load.cog_or_origin)
    return abs(sample.payload_kg - load.mass_kg) <= 1e-6 and all(
        abs(a - b) <= _SAME_M for a, b in zip(sample.payload_cog_m, cog, strict=True)
    )


def _rtde_text(payload: bytes) -> str:
    """An RTDE v2 text message: ``>B`` length, message, ``>B`` length, source, level."""
    if not payload:
        return ""
    length = payload[0]
    message = payload[1 : 1 + length].decode("utf-8", "replace")
    rest = payload[1 + length :]
    source = rest[1 : 1 + rest[0]].decode("utf-8", "replace") if rest else ""
    return f"{source}: {message}" if source else message


def _printed(values: tuple[float, ...]) -> str:
    return "[" + ", ".join(repr(v) for v in values) + "]"
