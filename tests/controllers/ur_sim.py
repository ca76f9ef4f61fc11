"""A Universal Robots e-Series controller, in memory: its RTDE interface (TCP 30004) and its
secondary client interface (TCP 30002).

Written from UR's documents and UR's own clients, not from tcpcal's connector:

RTDE (the *Real-Time Data Exchange (RTDE) Guide*,
docs.universal-robots.com/tutorials/communication-protocol-tutorials/rtde-guide.html, and UR's
Python client UniversalRobots/RTDE_Python_Client_Library ``rtde/rtde.py``,
``rtde/serialize.py``): every package is ``>HB`` (size including the 3-byte header, type)
then its payload, big-endian. Types: ``V`` RTDE_REQUEST_PROTOCOL_VERSION (``>H`` version,
answered ``>B`` accepted; this controller speaks protocol 2 only and answers 0 to another),
``v`` RTDE_GET_URCONTROL_VERSION (answered ``>IIII`` major, minor, bugfix, build),
``O`` RTDE_CONTROL_PACKAGE_SETUP_OUTPUTS (``>d`` frequency then comma-separated variable names,
answered ``>B`` recipe id then comma-separated types, ``NOT_FOUND`` for a name the controller
does not serve), ``I`` RTDE_CONTROL_PACKAGE_SETUP_INPUTS (names, answered id and types,
``IN_USE`` for an input another client holds), ``S`` RTDE_CONTROL_PACKAGE_START and ``P``
RTDE_CONTROL_PACKAGE_PAUSE (``>B`` accepted), ``U`` RTDE_DATA_PACKAGE (``>B`` recipe id then
the recipe's values: DOUBLE ``d``, VECTOR6D ``6d``, VECTOR3D ``3d``, INT32 ``i``, UINT32 ``I``,
UINT64 ``Q``, UINT8 ``B``, BOOL ``?``, VECTOR6INT32 ``6i``, VECTOR6UINT32 ``6I``) and ``M``
RTDE_TEXT_MESSAGE (v2: ``>B`` length, message, ``>B`` length, source, ``>B`` level 0
exception, 1 error, 2 warning, 3 info). Once started, data packages go out at the recipe's
frequency (at most 500 Hz, the e-Series control loop); paused, none. Each carries the
values of its control cycle: ``timestamp`` ("Time elapsed since the controller was started
[s]", the guide's output table) is the cycle's, so the packages of a 50 Hz recipe are
stamped 20 ms apart whenever they leave (a loaded machine delays the sending, not the
controller's clock); one left more than `CATCH_UP_S` behind (a stalled simulator) resumes at
the current cycle rather than sending every package it missed. The variables and
their types are those of the client's ``examples/record_configuration.xml`` (UR's list of
every output field). ``tcp_offset`` (the active TCP, x y z in m and a rotation vector in
rad) is served although the guide omits it, from PolyScope 3.12.0 / 5.5.1 on:
Universal_Robots_Client_Library PR #110 ("tcp_offset isn't available before software
version 3.12.0 and 5.5.1") and ``doc/polyscope_compatibility.rst``; an older controller
answers NOT_FOUND for it, as a PolyScope 3.7 robot did (Universal_Robots_ROS_Driver #605).
A recipe with a NOT_FOUND is not kept (its id is 0): this simulator's choice, the clients
all treat it as a failed setup. What the ur-rtde client (SDU Robotics, ``src/rtde.cpp``
1.6.5) does and this controller tolerates, as a real one must: a trailing comma after the
last name, the version asked twice, text messages skipped by the receiving thread, a fixed
port 30004 (`UrSimulator` can listen on 30004 of another 127.x address).

The secondary interface (the URScript manual, "Connecting to URControl": a program is sent
as text, ``def`` or ``sec`` in the first column, the other lines indented, ``end`` in the
first column; the client should read what the controller sends): the controller sends
packages ``>iB`` (size including the 5-byte header, type): on connection a ROBOT_MESSAGE
(20) VERSION (3), then ROBOT_STATE (16) packages of sub-packages ``>IB`` (size, type) at
10 Hz, here ROBOT_MODE_DATA (0) alone. The layouts are those of UR's own test server
(Universal_Robots_Client_Library ``tests/fake_primary_server.cpp``): a robot message is
``>QbB`` timestamp, source, type, then its body; TEXT (0) the text; ERROR_CODE (6)
``>iiiII`` code, argument, report level, data type, data, then the text; RUNTIME_EXCEPTION
(10) ``>II`` line, column, then the text. A ``sec`` program runs beside the running program;
a ``def`` program (or a bare line, which real controllers run as a one-line program) replaces
it, so the running program stops (Universal_Robots_ROS2_Driver #783). A program's
``set_tcp(p[x, y, z, rx, ry, rz])`` sets the live TCP (m, rad), ``set_payload(m[, [cx, cy,
cz]])``, ``set_payload_mass``, ``set_payload_cog`` and ``set_target_payload(m, [cog][,
[inertia]])`` the payload; they hold until a program is played, which sets the
installation's TCP and payload again (UR's payload article; the ROS2 driver #783: "TCP set
back to zero" once a program starts).

What the controller refuses: not in remote control, the interface is read-only and a program
is ignored with error code C210 A0 (report level VIOLATION), as UR's Client Library reads it
(``src/primary/primary_client.cpp``: "C210 means that the primary client is connected to a
read-only primary interface"); a robot that is not RUNNING or not in a NORMAL / REDUCED
safety mode (a protective stop) ignores it with a TEXT message in this simulator's own words
(no capture from a controller was found); a value that is not a pose is a RUNTIME_EXCEPTION.

The fault hook (`Faults`) names each RTDE request by its command (``RTDE_CONTROL_PACKAGE_START``
...) and each complete program received on the secondary interface ``script``: "before" the
controller goes silent without applying it, "after" it applies it first. Silent, no data
package, state package or answer leaves on any connection. `hold_inputs` plays a session left
behind (an RTDE client that set up inputs and never closed: the next one meets IN_USE);
`open_connections` counts what clients left open.

Poses are UR's: x, y, z in m and a rotation vector in rad. The test sets the flange in the
base frame (`set_flange`, mm), the joints (`set_joints`, deg) and plays the operator
(`pendant_set_tcp`, `play_program`, `protective_stop`, `remote_control`);
``actual_TCP_pose`` = flange * tcp_offset. `moving_mm_per_s` moves the flange along base x.
Values are computed with this module's own numpy and scipy.
"""

from __future__ import annotations

import re
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from tests.controllers.simbase import TcpSimulator

RTDE_PORT = 30004
SECONDARY_PORT = 30002

# RTDE package types (the guide; rtde.py Command)
REQUEST_PROTOCOL_VERSION = ord("V")
GET_URCONTROL_VERSION = ord("v")
TEXT_MESSAGE = ord("M")
DATA_PACKAGE = ord("U")
SETUP_OUTPUTS = ord("O")
SETUP_INPUTS = ord("I")
START = ord("S")
PAUSE = ord("P")
COMMAND_NAMES = {
    REQUEST_PROTOCOL_VERSION: "RTDE_REQUEST_PROTOCOL_VERSION",
    GET_URCONTROL_VERSION: "RTDE_GET_URCONTROL_VERSION",
    TEXT_MESSAGE: "RTDE_TEXT_MESSAGE",
    DATA_PACKAGE: "RTDE_DATA_PACKAGE",
    SETUP_OUTPUTS: "RTDE_CONTROL_PACKAGE_SETUP_OUTPUTS",
    SETUP_INPUTS: "RTDE_CONTROL_PACKAGE_SETUP_INPUTS",
    START: "RTDE_CONTROL_PACKAGE_START",
    PAUSE: "RTDE_CONTROL_PACKAGE_PAUSE",
}
# RTDE text message levels
EXCEPTION, ERROR, WARNING, INFO = 0, 1, 2, 3

# Secondary interface (fake_primary_server.cpp, primary/package_header.h, robot_message.h)
ROBOT_STATE = 16
ROBOT_MESSAGE = 20
MESSAGE_TEXT = 0
MESSAGE_VERSION = 3
MESSAGE_ERROR_CODE = 6
MESSAGE_RUNTIME_EXCEPTION = 10
ROBOT_MODE_DATA = 0
REPORT_VIOLATION = 3
READ_ONLY_INTERFACE = 210  # C210
STATE_PERIOD_S = 0.1
#: How far behind its cycle an output recipe may fall and still send every package it owes
#: (a few: the watcher's rounds met a 1 s backlog of them as a late drift, test_ur_controller).
CATCH_UP_S = 0.1

# Modes (ur_client_library/ur/datatypes.h; the RTDE guide's robot_mode and safety_mode)
ROBOT_MODE_RUNNING = 7
SAFETY_NORMAL, SAFETY_REDUCED, SAFETY_PROTECTIVE_STOP = 1, 2, 3
RUNTIME_STOPPED, RUNTIME_PLAYING = 1, 2

FORMATS = {
    "DOUBLE": "d",
    "VECTOR6D": "6d",
    "VECTOR3D": "3d",
    "INT32": "i",
    "UINT32": "I",
    "UINT64": "Q",
    "UINT8": "B",
    "BOOL": "?",
    "VECTOR6INT32": "6i",
    "VECTOR6UINT32": "6I",
}

_OUTPUTS = (
    "timestamp DOUBLE;target_q VECTOR6D;target_qd VECTOR6D;target_qdd VECTOR6D;"
    "target_current VECTOR6D;target_moment VECTOR6D;actual_q VECTOR6D;actual_qd VECTOR6D;"
    "actual_current VECTOR6D;actual_current_as_torque VECTOR6D;joint_control_output VECTOR6D;"
    "actual_TCP_pose VECTOR6D;actual_TCP_speed VECTOR6D;actual_TCP_force VECTOR6D;"
    "target_TCP_pose VECTOR6D;target_TCP_speed VECTOR6D;actual_digital_input_bits UINT64;"
    "joint_temperatures VECTOR6D;actual_execution_time DOUBLE;robot_mode INT32;"
    "joint_mode VECTOR6INT32;safety_status INT32;actual_tool_accelerometer VECTOR3D;"
    "speed_scaling DOUBLE;target_speed_fraction DOUBLE;actual_momentum DOUBLE;"
    "actual_main_voltage DOUBLE;actual_robot_voltage DOUBLE;actual_robot_current DOUBLE;"
    "actual_joint_voltage VECTOR6D;actual_digital_output_bits UINT64;runtime_state UINT32;"
    "joint_position_deviation_ratio DOUBLE;payload DOUBLE;payload_cog VECTOR3D;"
    "payload_inertia VECTOR6D;ft_raw_wrench VECTOR6D;script_control_line UINT32;"
    "actual_current_window VECTOR6D;elbow_position VECTOR3D;elbow_velocity VECTOR3D;"
    "robot_status_bits UINT32;safety_status_bits UINT32;safety_mode INT32;io_current DOUBLE;"
    "tool_mode UINT32;tcp_force_scalar DOUBLE;tcp_offset VECTOR6D;analog_io_types UINT32;"
    "standard_analog_input0 DOUBLE;standard_analog_input1 DOUBLE;"
    "standard_analog_output0 DOUBLE;standard_analog_output1 DOUBLE;"
    "tool_analog_input_types UINT32;tool_analog_input0 DOUBLE;tool_analog_input1 DOUBLE;"
    "tool_output_voltage INT32;tool_output_current DOUBLE;tool_temperature DOUBLE;"
    "tool_output_mode UINT8;tool_digital_output0_mode UINT8;tool_digital_output1_mode UINT8;"
    "euromap67_input_bits UINT32;euromap67_output_bits UINT32;euromap67_24V_voltage DOUBLE;"
    "euromap67_24V_current DOUBLE;actual_configurable_digital_input_bits UINT64;"
    "actual_configurable_digital_output_bits UINT64;encoder0_raw INT32;encoder1_raw INT32"
)
_INPUTS = (
    "speed_slider_mask UINT32;speed_slider_fraction DOUBLE;standard_digital_output_mask UINT8;"
    "configurable_digital_output_mask UINT8;tool_digital_output_mask UINT8;"
    "standard_digital_output UINT8;configurable_digital_output UINT8;"
    "tool_digital_output UINT8;standard_analog_output_mask UINT8;"
    "standard_analog_output_type UINT8;standard_analog_output_0 DOUBLE;"
    "standard_analog_output_1 DOUBLE;external_force_torque VECTOR6D"
)


def _registers(direction: str) -> dict[str, str]:
    """The general-purpose registers of one direction ("input" or "output")."""
    names = {
        f"{direction}_bit_registers0_to_31": "UINT32",
        f"{direction}_bit_registers32_to_63": "UINT32",
    }
    names |= {f"{direction}_bit_register_{i}": "BOOL" for i in range(64, 128)}
    names |= {f"{direction}_int_register_{i}": "INT32" for i in range(48)}
    names |= {f"{direction}_double_register_{i}": "DOUBLE" for i in range(48)}
    return names


def _table(text: str) -> dict[str, str]:
    return dict(item.split(" ") for item in text.split(";"))


#: Every input field and its type (record_configuration.xml's "in" recipe).
INPUT_TYPES: dict[str, str] = _table(_INPUTS) | _registers("input")
#: Every output field and its type; the input registers can be read as outputs too.
OUTPUT_TYPES: dict[str, str] = _table(_OUTPUTS) | _registers("output") | _registers("input")
#: Output fields served only from a version on: (CB3 3.x, e-Series 5.x) minimum.
SINCE: dict[str, tuple[tuple[int, int, int], tuple[int, int, int]]] = {
    "tcp_offset": ((3, 12, 0), (5, 5, 1)),
    "actual_current_as_torque": ((99, 0, 0), (5, 23, 0)),
}

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_CALL = re.compile(
    r"^\s*(set_tcp|set_payload|set_payload_mass|set_payload_cog|set_target_payload)"
    r"\((.*)\)\s*$"
)


def pose_matrix(pose: Iterable[float]) -> NDArray[np.float64]:
    """A UR pose (m, rotation vector in rad) as a 4x4 matrix in m."""
    values = [float(v) for v in pose]
    matrix = np.eye(4)
    matrix[:3, :3] = Rotation.from_rotvec(values[3:6]).as_matrix()
    matrix[:3, 3] = values[:3]
    return matrix


def matrix_pose(matrix: NDArray[np.float64]) -> tuple[float, ...]:
    """A 4x4 matrix in m as a UR pose (m, rotation vector in rad)."""
    rotvec = Rotation.from_matrix(matrix[:3, :3]).as_rotvec()
    return (*(float(v) for v in matrix[:3, 3]), *(float(v) for v in rotvec))


@dataclass
class Recipe:
    """One output or input recipe of an RTDE session."""

    id: int
    names: list[str]
    types: list[str]
    frequency: float = 0.0
    next_due: float = 0.0

    @property
    def format(self) -> str:
        return ">B" + "".join(FORMATS[t] for t in self.types)


@dataclass
class RtdeSession:
    """One RTDE client's connection: its protocol, its recipes, whether it streams."""

    conn: socket.socket
    protocol: int = 1
    outputs: dict[int, Recipe] = field(default_factory=dict)
    inputs: dict[int, Recipe] = field(default_factory=dict)
    started: bool = False
    #: RTDE text messages the controller has yet to send on this connection
    outbox: list[bytes] = field(default_factory=list)
    received_text: list[str] = field(default_factory=list)


@dataclass
class Program:
    """A program received on the secondary interface."""

    text: str
    kind: str  # "def" | "sec" | "line"
    applied: bool = False
    refused: str | None = None


class UrSimulator(TcpSimulator):
    """RTDE and the secondary interface of an in-memory UR e-Series controller.

    `host` may be any 127.x.y.z address; `rtde_port` / `secondary_port` 0 take free ports
    (the real ones are 30004 and 30002)."""

    name = "UR RTDE"

    def __init__(
        self,
        *,
        host: str = "127.0.0.1",
        rtde_port: int = 0,
        secondary_port: int = 0,
        version: tuple[int, int, int, int] = (5, 15, 0, 118321),
    ) -> None:
        super().__init__()
        self.host = host
        self.port = rtde_port
        self.secondary_port = secondary_port
        self.version = version
        self._data_lock = threading.RLock()
        #: When the controller started (time.monotonic()): `timestamp` counts from it.
        self.started_at = time.monotonic()
        # the robot: flange in the base frame (m), joints (rad), live and installation TCP
        self._flange = np.eye(4)
        self._flange[:3, 3] = (0.4, -0.1, 0.5)
        self._flange[:3, :3] = Rotation.from_rotvec([np.pi, 0.0, 0.0]).as_matrix()
        self._moved_since = time.monotonic()
        self.joints_rad: list[float] = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]
        self.installation_tcp: tuple[float, ...] = (0.0,) * 6
        self._tcp: tuple[float, ...] = self.installation_tcp
        self.installation_payload: tuple[float, tuple[float, float, float]] = (0.0, (0.0, 0.0, 0.0))
        self.payload_kg = 0.0
        self.payload_cog_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.payload_inertia: tuple[float, ...] = (0.0,) * 6
        self.robot_mode = ROBOT_MODE_RUNNING
        self.safety_mode = SAFETY_NORMAL
        self.in_remote_control = True
        self.program_running = True
        #: a moving robot: the flange moves along base x this fast (mm/s)
        self.moving_mm_per_s = 0.0
        # what clients did
        self.programs: list[Program] = []
        self.secondary_messages: list[str] = []
        self.rtde_sessions: list[RtdeSession] = []
        self._secondary_open = 0
        #: input fields a session left behind holds (IN_USE for every other client)
        self.held_inputs: set[str] = set()

    def start(self) -> UrSimulator:
        self._running = True
        self.port = self.add_listener(self.port, self.serve)
        self.secondary_port = self.add_listener(self.secondary_port, self.serve_secondary)
        return self

    @property
    def rtde_port(self) -> int:
        return self.port

    @classmethod
    def on_real_ports(cls, **kwargs: object) -> UrSimulator:
        """A started simulator listening on RTDE 30004 and secondary 30002 of the first free
        127.30.x.y address (ur-rtde's RTDEReceiveInterface has no port argument)."""
        for index in range(2, 250):
            sim = cls(
                host=f"127.30.{index // 100}.{index % 100 + 1}",
                rtde_port=RTDE_PORT,
                secondary_port=SECONDARY_PORT,
                **kwargs,  # type: ignore[arg-type]
            )
            try:
                return sim.start()
            except OSError:
                sim.stop()
        raise OSError("no 127.30.x.y address has ports 30004 and 30002 free")

    # --- the robot and its operator -----------------------------------------------------

    def set_flange(self, position_mm: Iterable[float], rotation: NDArray[np.float64]) -> None:
        """The flange in the robot's base frame: position (mm) and 3x3 rotation."""
        with self._data_lock:
            self._flange[:3, 3] = np.asarray(list(position_mm), dtype=float) / 1000.0
            self._flange[:3, :3] = np.asarray(rotation, dtype=float)
            self._moved_since = time.monotonic()

    def flange(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The flange's position (mm) and 3x3 rotation in the base frame, now."""
        with self._data_lock:
            matrix = self._flange_now()
        return matrix[:3, 3] * 1000.0, matrix[:3, :3]

    def set_joints(self, *degrees: float) -> None:
        """The six joints (deg)."""
        with self._data_lock:
            self.joints_rad = [float(np.radians(v)) for v in degrees]

    def tcp(self) -> tuple[float, ...]:
        """The live TCP (``tcp_offset``): x, y, z in m, rotation vector in rad."""
        with self._data_lock:
            return self._tcp

    def pendant_set_tcp(self, pose: Iterable[float]) -> None:
        """The operator sets the installation's TCP at the pendant (Installation > General >
        TCP, with no program running it is the active TCP at once)."""
        values = tuple(float(v) for v in pose)
        with self._data_lock:
            self.installation_tcp = values
            self._tcp = values

    def play_program(self) -> None:
        """A program is played: it starts with the installation's TCP and payload, whatever a
        script set before."""
        with self._data_lock:
            self._tcp = self.installation_tcp
            self.payload_kg, self.payload_cog_m = self.installation_payload
            self.program_running = True

    def protective_stop(self, on: bool = True) -> None:
        with self._data_lock:
            self.safety_mode = SAFETY_PROTECTIVE_STOP if on else SAFETY_NORMAL

    def remote_control(self, on: bool) -> None:
        """Local control (False): the secondary interface is read-only."""
        with self._data_lock:
            self.in_remote_control = on

    def hold_inputs(self, *names: str) -> None:
        """A session left behind: a client set these inputs up and never closed."""
        with self._data_lock:
            self.held_inputs.update(names)

    def say(self, message: str, *, source: str = "URControl", level: int = INFO) -> None:
        """An RTDE text message to every RTDE client."""
        package = _rtde(TEXT_MESSAGE, _text_payload(message, source, level))
        with self._data_lock:
            for session in self.rtde_sessions:
                session.outbox.append(package)

    def open_connections(self) -> dict[str, int]:
        """Connections clients hold open now, per service."""
        with self._data_lock:
            return {"rtde": len(self.rtde_sessions), "secondary": self._secondary_open}

    # --- values ---------------------------------------------------------------------------

    def _flange_now(self) -> NDArray[np.float64]:
        matrix = self._flange.copy()
        if self.moving_mm_per_s:
            matrix[0, 3] += self.moving_mm_per_s / 1000.0 * (time.monotonic() - self._moved_since)
        return matrix

    def outputs(self) -> dict[str, object]:
        """The values an output recipe can name, now (the rest are zeros of their type)."""
        with self._data_lock:
            tcp_pose = matrix_pose(self._flange_now() @ pose_matrix(self._tcp))
            running = self.program_running
            protective = self.safety_mode == SAFETY_PROTECTIVE_STOP
            return {
                "timestamp": time.monotonic() - self.started_at,
                "actual_q": list(self.joints_rad),
                "target_q": list(self.joints_rad),
                "actual_TCP_pose": list(tcp_pose),
                "target_TCP_pose": list(tcp_pose),
                "tcp_offset": list(self._tcp),
                "robot_mode": self.robot_mode,
                "safety_mode": self.safety_mode,
                "safety_status": self.safety_mode,
                "runtime_state": RUNTIME_PLAYING if running else RUNTIME_STOPPED,
                # bit 0 power on, bit 1 program running
                "robot_status_bits": 1 | (2 if running else 0),
                # bit 0 normal mode, bit 1 reduced mode, bit 2 protective stopped
                "safety_status_bits": 4 if protective else 1,
                "payload": self.payload_kg,
                "payload_cog": list(self.payload_cog_m),
                "payload_inertia": list(self.payload_inertia),
                "speed_scaling": 1.0,
                "target_speed_fraction": 1.0,
            }

    def _served(self, name: str) -> str:
        """The type of output `name` on this controller's version, or NOT_FOUND."""
        kind = OUTPUT_TYPES.get(name)
        since = SINCE.get(name)
        if kind is not None and since is not None:
            cb3, e_series = since
            needed = e_series if self.version[0] >= 5 else cb3
            if tuple(self.version[:3]) < needed:
                return "NOT_FOUND"
        return kind or "NOT_FOUND"

    # --- RTDE -----------------------------------------------------------------------------

    def serve(self, conn: socket.socket) -> None:
        """One RTDE client: requests answered, data packages while started."""
        session = RtdeSession(conn)
        with self._data_lock:
            self.rtde_sessions.append(session)
        try:
            self._rtde_loop(session)
        finally:
            with self._data_lock:
                self.rtde_sessions.remove(session)

    def _rtde_loop(self, session: RtdeSession) -> None:
        buffer = b""
        while True:
            session.conn.settimeout(self._wait(session))
            try:
                chunk = session.conn.recv(65536)
            except TimeoutError:
                chunk = None
            if chunk == b"":
                return
            if chunk:
                buffer += chunk
                while len(buffer) >= 3:
                    size, kind = struct.unpack_from(">HB", buffer)
                    if size < 3 or len(buffer) < size:
                        break
                    payload, buffer = buffer[3:size], buffer[size:]
                    self._rtde_request(session, kind, payload)
            if not self.stalled:
                self._rtde_send_due(session)

    def _wait(self, session: RtdeSession) -> float:
        """How long to wait for a request before a data package is due."""
        if self.stalled or not session.started or not session.outputs:
            return 0.05
        due = min(r.next_due for r in session.outputs.values())
        return min(0.05, max(0.0005, due - time.monotonic()))

    def _rtde_request(self, session: RtdeSession, kind: int, payload: bytes) -> None:
        name = COMMAND_NAMES.get(kind, f"RTDE package {kind}")
        stop = self.fault_at(name)
        if stop == "before" or self.stalled:
            return
        reply = self._rtde_answer(session, kind, payload)
        self.slow()
        if stop == "after":
            self.stalled = True
            return
        if reply is not None:
            session.conn.sendall(reply)

    def _rtde_answer(self, session: RtdeSession, kind: int, payload: bytes) -> bytes | None:
        handlers: dict[int, Callable[[RtdeSession, bytes], bytes | None]] = {
            REQUEST_PROTOCOL_VERSION: self._protocol_version,
            GET_URCONTROL_VERSION: lambda _s, _p: _rtde(kind, struct.pack(">IIII", *self.version)),
            SETUP_OUTPUTS: self._setup_outputs,
            SETUP_INPUTS: self._setup_inputs,
            START: self._start,
            PAUSE: self._pause,
            DATA_PACKAGE: self._inputs_received,
            TEXT_MESSAGE: self._text_received,
        }
        handler = handlers.get(kind)
        if handler is None:
            return _rtde(TEXT_MESSAGE, _text_payload(f"unknown package type {kind}", "RTDE", ERROR))
        try:
            return handler(session, payload)
        except (struct.error, IndexError):
            words = f"malformed {COMMAND_NAMES[kind]} package"
            return _rtde(TEXT_MESSAGE, _text_payload(words, "RTDE", ERROR))

    def _protocol_version(self, session: RtdeSession, payload: bytes) -> bytes:
        (version,) = struct.unpack_from(">H", payload)
        accepted = version == 2
        if accepted:
            session.protocol = 2
        return _rtde(REQUEST_PROTOCOL_VERSION, struct.pack(">B", accepted))

    def _setup_outputs(self, session: RtdeSession, payload: bytes) -> bytes:
        (frequency,) = struct.unpack_from(">d", payload)
        names = _names(payload[8:])
        types = [self._served(n) for n in names]
        valid = bool(names) and "NOT_FOUND" not in types and 0 < frequency <= 500
        recipe_id = 0
        if valid:
            recipe_id = len(session.outputs) + len(session.inputs) + 1
            recipe = Recipe(recipe_id, names, types, frequency, time.monotonic())
            session.outputs[recipe_id] = recipe
        return _rtde(SETUP_OUTPUTS, struct.pack(">B", recipe_id) + ",".join(types).encode())

    def _setup_inputs(self, session: RtdeSession, payload: bytes) -> bytes:
        names = _names(payload)
        with self._data_lock:
            held = set(self.held_inputs)
            for other in self.rtde_sessions:
                if other is not session:
                    held.update(n for r in other.inputs.values() for n in r.names)
        types = [
            "IN_USE" if n in held and n in INPUT_TYPES else INPUT_TYPES.get(n, "NOT_FOUND")
            for n in names
        ]
        recipe_id = 0
        if names and not {"IN_USE", "NOT_FOUND"} & set(types):
            recipe_id = len(session.outputs) + len(session.inputs) + 1
            session.inputs[recipe_id] = Recipe(recipe_id, names, types)
        return _rtde(SETUP_INPUTS, struct.pack(">B", recipe_id) + ",".join(types).encode())

    def _start(self, session: RtdeSession, _payload: bytes) -> bytes:
        accepted = bool(session.outputs or session.inputs)
        if accepted:
            session.started = True
            now = time.monotonic()
            for recipe in session.outputs.values():
                recipe.next_due = now
        return _rtde(START, struct.pack(">B", accepted))

    def _pause(self, session: RtdeSession, _payload: bytes) -> bytes:
        session.started = False
        return _rtde(PAUSE, struct.pack(">B", 1))

    def _inputs_received(self, session: RtdeSession, payload: bytes) -> None:
        recipe = session.inputs.get(payload[0]) if payload else None
        if recipe is None or not session.started:
            return None
        struct.unpack(recipe.format, payload)  # a malformed package raises: the link drops
        return None

    def _text_received(self, session: RtdeSession, payload: bytes) -> None:
        length = payload[0]
        session.received_text.append(payload[1 : 1 + length].decode("utf-8", "replace"))
        return None

    def _rtde_send_due(self, session: RtdeSession) -> None:
        with self._data_lock:
            outbox, session.outbox = session.outbox, []
        for package in outbox:
            session.conn.sendall(package)
        if not session.started:
            return
        now = time.monotonic()
        due = [r for r in session.outputs.values() if r.next_due <= now]
        if not due:
            return
        values = self.outputs()
        for recipe in due:
            stamped = {**values, "timestamp": recipe.next_due - self.started_at}
            session.conn.sendall(_rtde(DATA_PACKAGE, _data(recipe, stamped)))
            period = 1.0 / recipe.frequency
            recipe.next_due += period
            if recipe.next_due < now - CATCH_UP_S:  # far behind: resume at this cycle
                recipe.next_due += period * ((now - recipe.next_due) // period)

    # --- the secondary interface ---------------------------------------------------------

    def serve_secondary(self, conn: socket.socket) -> None:
        """One secondary client: the version message, state at 10 Hz, programs run."""
        with self._data_lock:
            self._secondary_open += 1
        try:
            if not self.stalled:
                conn.sendall(self._version_message())
            self._secondary_loop(conn)
        finally:
            with self._data_lock:
                self._secondary_open -= 1

    def _secondary_loop(self, conn: socket.socket) -> None:
        text = ""
        next_state = time.monotonic()
        while True:
            conn.settimeout(max(0.001, min(0.05, next_state - time.monotonic())))
            try:
                chunk = conn.recv(65536)
            except TimeoutError:
                chunk = None
            if chunk == b"":
                return
            if chunk:
                text += chunk.decode("latin-1")
                programs, text = split_programs(text)
                for program in programs:
                    self._program(conn, program)
            if not self.stalled and time.monotonic() >= next_state:
                conn.sendall(self._state_package())
                next_state = time.monotonic() + STATE_PERIOD_S

    def _program(self, conn: socket.socket, program: Program) -> None:
        self.programs.append(program)
        stop = self.fault_at("script")
        if stop == "before" or self.stalled:
            return
        reply = self._run(program)
        self.slow()
        if stop == "after":
            self.stalled = True
            return
        if reply is not None:
            conn.sendall(reply)

    def _run(self, program: Program) -> bytes | None:
        """Run `program` unless the controller refuses it: the refusal's message, if any."""
        with self._data_lock:
            if not self.in_remote_control:
                program.refused = "C210A0 read-only interface: the robot is in local control"
                return self._robot_message(
                    MESSAGE_ERROR_CODE,
                    struct.pack(">iiiII", READ_ONLY_INTERFACE, 0, REPORT_VIOLATION, 0, 0)
                    + b"Interface is read-only: the robot is not in remote control",
                )
            if self.robot_mode != ROBOT_MODE_RUNNING or self.safety_mode not in (
                SAFETY_NORMAL,
                SAFETY_REDUCED,
            ):
                program.refused = "the robot cannot run a program now"
                words = (
                    "Protective stop: program not started"
                    if self.safety_mode == SAFETY_PROTECTIVE_STOP
                    else f"Robot mode {self.robot_mode}: program not started"
                )
                return self._robot_message(MESSAGE_TEXT, words.encode())
            return self._statements(program)

    def _statements(self, program: Program) -> bytes | None:
        for number, line in enumerate(program.text.splitlines(), 1):
            match = _CALL.match(line)
            if match is None:
                continue
            call, arguments = match.groups()
            try:
                self._apply(call, arguments)
            except ValueError as exc:
                program.refused = str(exc)
                return self._robot_message(
                    MESSAGE_RUNTIME_EXCEPTION, struct.pack(">II", number, 1) + str(exc).encode()
                )
        program.applied = True
        if program.kind != "sec":
            self.program_running = False  # a def program replaced the running one and ended
        return None

    def _apply(self, call: str, arguments: str) -> None:
        """One call of a program (the data lock held)."""
        if call == "set_tcp":
            self._tcp = _pose_literal(arguments)
            return
        lists = [_numbers(m) for m in re.findall(r"\[([^\]]*)\]", arguments)]
        head = re.split(r",\s*\[", arguments, maxsplit=1)[0]
        if call == "set_payload_cog":
            self.payload_cog_m = _vector3(lists[0] if lists else [])
            return
        mass = _numbers(head)
        if len(mass) != 1 or mass[0] < 0:
            raise ValueError(f"{call}: the mass must be one number of kg, got {head!r}")
        self.payload_kg = mass[0]
        if lists:
            self.payload_cog_m = _vector3(lists[0])
        if call == "set_target_payload" and len(lists) > 1:
            self.payload_inertia = tuple(lists[1])

    def _version_message(self) -> bytes:
        project = b"URControl"
        major, minor, bugfix, build = self.version
        body = (
            struct.pack(">b", len(project))
            + project
            + struct.pack(">BBii", major, minor, bugfix, build)
            + b"26-11-2026, 10:00:00"
        )
        return self._robot_message(MESSAGE_VERSION, body, record=False)

    def _robot_message(self, kind: int, body: bytes, *, record: bool = True) -> bytes:
        if record:
            self.secondary_messages.append(body.decode("latin-1"))
        stamp = int((time.monotonic() - self.started_at) * 1e6)
        return _secondary(ROBOT_MESSAGE, struct.pack(">QbB", stamp, -1, kind) + body)

    def _state_package(self) -> bytes:
        with self._data_lock:
            data = struct.pack(
                ">Q7?bBddd",
                int((time.monotonic() - self.started_at) * 1e6),
                True,
                True,
                True,
                False,
                self.safety_mode == SAFETY_PROTECTIVE_STOP,
                self.program_running,
                False,
                self.robot_mode,
                0,
                1.0,
                1.0,
                1.0,
            )
        sub = struct.pack(">IB", 5 + len(data), ROBOT_MODE_DATA) + data
        return _secondary(ROBOT_STATE, sub)


# --- framing and parsing (module level: the simulator's own readers) ----------------------


def _rtde(kind: int, payload: bytes) -> bytes:
    return struct.pack(">HB", 3 + len(payload), kind) + payload


def _secondary(kind: int, body: bytes) -> bytes:
    return struct.pack(">iB", 5 + len(body), kind) + body


def _text_payload(message: str, source: str, level: int) -> bytes:
    text, origin = message.encode()[:255], source.encode()[:255]
    return bytes([len(text)]) + text + bytes([len(origin)]) + origin + bytes([level])


def _names(payload: bytes) -> list[str]:
    """Comma-separated variable names; an empty one (ur-rtde's trailing comma) is dropped."""
    return [n.strip() for n in payload.decode("utf-8", "replace").split(",") if n.strip()]


def _zero(kind: str) -> object:
    count = {"VECTOR6D": 6, "VECTOR3D": 3, "VECTOR6INT32": 6, "VECTOR6UINT32": 6}.get(kind)
    scalar: object = 0.0 if kind.endswith("D") or kind == "DOUBLE" else 0
    if kind == "BOOL":
        scalar = False
    return [scalar] * count if count else scalar


def _data(recipe: Recipe, values: dict[str, object]) -> bytes:
    flat: list[object] = [recipe.id]
    for name, kind in zip(recipe.names, recipe.types, strict=True):
        value = values.get(name, _zero(kind))
        if isinstance(value, list):
            flat.extend(value)
        else:
            flat.append(value)
    return struct.pack(recipe.format, *flat)


def split_programs(text: str) -> tuple[list[Program], str]:
    """The complete programs at the head of `text` and what is left to wait for: a ``def`` or
    ``sec`` program ends at a line ``end`` in the first column, any other line is a
    one-line program."""
    programs: list[Program] = []
    while "\n" in text:
        first = text.split("\n", 1)[0]
        if not first.strip():
            text = text.split("\n", 1)[1]
            continue
        kind = first.split(" ", 1)[0] if first.startswith(("def ", "sec ")) else "line"
        if kind == "line":
            programs.append(Program(first + "\n", kind))
            text = text.split("\n", 1)[1]
            continue
        end = re.search(r"^end[ \t]*\n", text, re.MULTILINE)
        if end is None:
            break
        programs.append(Program(text[: end.end()], kind))
        text = text[end.end() :]
    return programs, text


def _numbers(text: str) -> list[float]:
    found = re.findall(_NUMBER, text)
    rest = re.sub(_NUMBER, "", text).replace(",", "").strip()
    if rest:
        raise ValueError(f"not a list of numbers: {text!r}")
    return [float(v) for v in found]


def _vector3(values: list[float]) -> tuple[float, float, float]:
    if len(values) != 3:
        raise ValueError(f"a centre of gravity has 3 values, got {values}")
    return values[0], values[1], values[2]


def _pose_literal(arguments: str) -> tuple[float, ...]:
    """``p[x, y, z, rx, ry, rz]`` as six numbers; ValueError for anything else."""
    match = re.fullmatch(r"\s*p\[([^\]]*)\]\s*", arguments)
    values = _numbers(match.group(1)) if match else []
    if len(values) != 6 or not all(np.isfinite(values)):
        raise ValueError(f"set_tcp needs a pose p[x, y, z, rx, ry, rz], got {arguments!r}")
    return tuple(values)
