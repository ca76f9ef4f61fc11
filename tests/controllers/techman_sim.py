"""A Techman TM robot running TMflow, in memory: the Listen Node a project waits in (TCP 5890)
and the Ethernet Slave that serves the robot's data table (TCP 5891).

Written from Techman's documents, read through the copies and clients below; it imports
nothing from app/ (tests/test_simulators_independent.py), so a mistake the connector's writer
shares with the connector's reader cannot pass here.

The packets (Techman *Expression Editor and Listen Node* manual, I848 editions for TMflow
1.76-1.84, chapter "Listen Node"; the same framing in Techman's own driver,
TechmanRobotInc/tmr_ros2 ``tm_driver/src/tm_packet.cpp``): ``$HEADER,LENGTH,DATA,*CS\\r\\n``,
LENGTH the byte count of DATA in decimal, CS the XOR of every byte from the header's first
letter to the comma after DATA, in two hexadecimal digits. The manual's own examples, whose
checksums this module reproduces: ``$TMSCT,4,1,OK,*5C``, ``$TMSCT,13,3,ERROR;1;2;3,*3F``,
``$TMSCT,9,0,Listen1,*4C``, ``$TMSTA,9,00,false,,*37``, ``$CPERR,2,F1,*3F``.

The Listen Node (TCP 5890). The project's Listen node opens its socket server when the
project starts (the *Software Manual TMflow*, "Listen Node"; TMflow's log line "Listen opens
on <ip>:5890" at project start, TechmanRobotInc/tmr_ros1 issue 5): with no project running
nothing listens and a connection is refused. ``$TMSCT`` carries ``ID,SCRIPT``, the script's
commands one a line (``\\r\\n`` between them); the answer is ``ID,OK``, or ``ID,ERROR;n;m``
naming the lines (from 1) that are not valid, in which case none of the script runs (the
manual does not say whether the valid lines of a faulty script run: this controller runs
none). A script reaching the robot while the project is not waiting in the Listen node is
answered ``$CPERR,2,F1`` ("Listen Node is not active" in techmanpy's table) and nothing runs.
``$CPERR`` also answers a packet that cannot be read: 01 packet error (framing, length), 02
checksum error, 03 header error (a header this port does not serve), 04 packet data error.
When the flow enters the Listen node the robot tells the connected client
``$TMSCT,<len>,0,<node name>`` (the manual's ``Listen1`` example).

``$TMSTA`` (answered while the project runs, in the node or not): ``00`` asks whether the
project waits in the Listen node, answered ``00,true,<node name>`` or ``00,false,``; ``01,<tag>``
asks about a queue tag, answered ``01,<tag>,true`` (reached), ``false`` (pending) or ``none``
(no such tag).

Commands this controller runs (the manual's function list; techmanpy's ``TMSCT_commands``
writes the same calls): ``ChangeBase`` in its overloads (``ChangeBase("name")``, a base of
the base list, ``ChangeBase({X,Y,Z,RX,RY,RZ})`` and the six values spelled out, as
techmanpy's ``set_base`` writes them: the base in the robot base), ``ChangeTCP`` in its
overloads, ``ChangeTCP("name")`` (a TCP of the
TCP list), ``ChangeTCP({X,Y,Z,RX,RY,RZ})``, ``ChangeTCP({...}, weight)``,
``ChangeTCP({...}, weight, {9 inertia values: Ixx Iyy Izz and the mass centre frame X Y Z
RX RY RZ})`` and the same with the values spelled out (6, 7 or 16 numbers, as techmanpy
writes them); ``QueueTag(tag[, wait])`` (tag 1-15); ``ScriptExit()`` (the flow leaves the
node once the answer is sent). Any other command is a line in error. ChangeBase, ChangeTCP
and QueueTag enter the motion queue: the manual's second category of listen-node commands,
"placed in the queue and executed in order". The queue here runs at once unless
`queue_delay_s` > 0 (a robot still finishing a motion): a queued command then runs that
long after its script's OK, and a read before that finds the old TCP. A TCP given by values
alone carries no mass (TCP_Mass 0) and, not being a TCP of the list, no name (TCP_Name
reads ``""``): the manual says neither, this controller's choice; so for a base given by
values (Base_Name ``""``). The base list (`base_list`, name -> X Y Z RX RY RZ, TMflow's
default base ``RobotBase`` the robot base itself) is apart from the TCP list: a ChangeBase
changes the current base and nothing else, and a base of the list is changed only at the
pendant (`add_base`); a name not in the list, or not six numbers, is a line in error.

One client at a time: the manual does not say how many clients a Listen node serves; this
one serves the first connection and lets any other wait, accepted and unanswered, until the
first closes. A connection a dead session leaves open therefore blocks the next attempt,
which is what a connector must not leave behind.

The Ethernet Slave (TCP 5891; *Software Manual TMflow*, Appendix "Ethernet Slave" data
table, and its use in tmr_ros2 ``tm_svr_communication.cpp`` and techmanpy
``tmsvr_packet.py``). ``$TMSVR`` carries ``ID,MODE,CONTENT``. Mode 12, a read request in
STRING format: item names, one a line, answered in mode 12 (as tm_driver's READ_STRING
branch reads it; techmanpy 1.2 accepts it too) with ``Item=Value`` lines. Mode 13, the same in
JSON: ``[{"Item":"Coord_Robot_Tool"}]`` answered ``[{"Item":"Coord_Robot_Tool","Value":[...]}]``
(a reply a robot printed, kept in a public client script:
``$TMSVR,113,01,13,[{"Item":"Coord_Robot_Tool","Value":[-179.400269,343.784576,...]}],*09``:
numbers with six decimals, which this controller prints too, from the 32-bit floats it holds).
Modes 2 and 3 write items (``Item=Value``; JSON): every item served here is read-only,
answered in mode 0 ``05,ReadOnly;<item>``. An item the table does not have, or one not
checked in the Ethernet Slave's transmitted data table (`data_table`), answers
``04,NotExist;<item>``; content that cannot be read ``03,InvalidData``; a binary request (mode
11 or 1) or another mode ``01,NotSupport`` (this controller speaks no binary table). Answers
in mode 0 are ``ID,0,CODE,DESCRIPTION[;DATA]`` with techmanpy's code table (00 OK .. 07
ValueError). The data table is broadcast to every connected client, unasked, every
`broadcast_s` seconds (TMflow broadcasts it at the rate the Ethernet Slave is set to; here
in STRING format, mode 2, with the transaction ID ``0``, an ID the manual leaves to the
robot: a client must match its answers by its own ID and pass the rest by).

The items served (Appendix data table): ``Coord_Robot_Flange`` (the flange in the robot
base, X Y Z mm, RX RY RZ deg), ``Coord_Robot_Tool`` (the current TCP in the robot base: the
flange times ``TCP_Value``), ``Coord_Base_Flange`` / ``Coord_Base_Tool`` (the same in the
current base: inverse(``Base_Value``) times the pose in the robot base), ``Joint_Angle``
(J1-J6 deg), ``TCP_Value`` (the current TCP in the flange frame, read-only), ``TCP_Name``,
``TCP_Mass`` (kg), ``Base_Value`` (the current base in the robot base, X Y Z RX RY RZ,
read-only), ``Base_Name``, ``Project_Run``, ``Project_Pause``, ``Robot_Error``. RX RY RZ
turn about the fixed axes: R = Rz(RZ) Ry(RY) Rx(RX) (tm_driver's ``tm_pose_conversion.h``
builds rotations with ``setRPY``, that product), scipy's extrinsic ``"xyz"``. The joints and
the flange are the test's to set (`set_joints`, `set_flange`), not computed from each other;
`moving_per_read` makes the robot move (each read request finds the flange that many mm
further along base x and J1 that many degrees further).

The pendant and the flow (`select_tcp`, `set_current_tcp`, `add_tcp`, `start_project`,
`stop_project`, `enter_listen_node`, `leave_listen_node`, `add_base`, `select_base`): the
TCP and the base the robot moves by are the project's; a project start sets the TCP and the
base it was written with (`project_tcp`, a name of the TCP list, "NOTOOL" the flange itself;
`project_base`, a name of the base list), so a TCP or base changed through the Listen node
lasts only until the next start.

The fault hook (`Faults`) names a request by each command of a script ("ChangeBase",
"ChangeTCP",
"QueueTag", ...), "TMSTA 00" / "TMSTA 01", and "TMSVR <mode>": "before" leaves the script
unrun and the controller silent, "after" runs it and goes silent without the answer.
"""

from __future__ import annotations

import contextlib
import json
import re
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Self

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from tests.controllers.simbase import TcpSimulator

LISTEN_NODE_HEADERS = ("TMSCT", "TMSTA")
ETHERNET_SLAVE_HEADERS = ("TMSVR",)
#: $CPERR codes (the manual's table; techmanpy's CPERR_code)
PACKET_ERROR, CHECKSUM_ERROR, HEADER_ERROR, DATA_ERROR, NOT_IN_LISTEN_NODE = (
    "01",
    "02",
    "03",
    "04",
    "F1",
)
#: $TMSVR mode 0 answers (code, description)
SVR_OK = ("00", "OK")
SVR_NOT_SUPPORTED = ("01", "NotSupport")
SVR_INVALID_DATA = ("03", "InvalidData")
SVR_NOT_EXIST = ("04", "NotExist")
SVR_READ_ONLY = ("05", "ReadOnly")
BROADCAST_ID = "0"
POSE_ITEMS = ("Coord_Robot_Flange", "Coord_Robot_Tool", "Coord_Base_Flange", "Coord_Base_Tool")
ITEMS = (
    "Robot_Error",
    "Project_Run",
    "Project_Pause",
    "Joint_Angle",
    *POSE_ITEMS,
    "TCP_Name",
    "TCP_Value",
    "TCP_Mass",
    "Base_Name",
    "Base_Value",
)
NO_TOOL = "NOTOOL"
ROBOT_BASE = "RobotBase"

Arg = float | str | bool | list[float]
ItemValue = bool | str | float | tuple[float, ...]


@dataclass(frozen=True)
class Tcp:
    """A TCP as the controller holds it: X Y Z (mm) RX RY RZ (deg) in the flange frame, the
    tool's mass (kg) and inertia (Ixx Iyy Izz, mass centre frame X Y Z RX RY RZ), each a
    32-bit float."""

    values: tuple[float, ...]
    mass: float = 0.0
    inertia: tuple[float, ...] = (0.0,) * 9


def f32(values: tuple[float, ...] | list[float]) -> tuple[float, ...]:
    """What the controller's 32-bit floats hold for `values`."""
    return tuple(float(np.float32(v)) for v in values)


# --- the packets -------------------------------------------------------------------------


def checksum(body: bytes) -> int:
    """XOR of every byte of `body` (from the header to the comma after the data)."""
    value = 0
    for byte in body:
        value ^= byte
    return value


def packet(header: str, data: str) -> bytes:
    """``$HEADER,LENGTH,DATA,*CS\\r\\n``."""
    payload = data.encode("utf-8")
    body = f"{header},{len(payload)},".encode("ascii") + payload + b","
    return b"$" + body + b"*" + f"{checksum(body):02X}".encode("ascii") + b"\r\n"


@dataclass(frozen=True)
class Received:
    """One packet read: its header and data, or the $CPERR code it earns."""

    header: str
    data: str
    error: str | None = None


_END = re.compile(rb",\*[0-9A-Fa-f]{2}\r\n")


class PacketReader:
    """Cuts a byte stream into packets; a packet that cannot be read is reported with its
    $CPERR code and skipped (up to the next packet end)."""

    def __init__(self, headers: tuple[str, ...]) -> None:
        self.headers = headers
        self.buffer = b""

    def feed(self, chunk: bytes) -> list[Received]:
        self.buffer += chunk
        found: list[Received] = []
        while (item := self._next()) is not None:
            found.append(item)
        return found

    def _skip(self, error: str) -> Received:
        end = _END.search(self.buffer)
        self.buffer = self.buffer[end.end() :] if end else b""
        return Received("", "", error)

    def _next(self) -> Received | None:
        start = self.buffer.find(b"$")
        if start < 0:
            self.buffer = b""
            return None
        buf = self.buffer = self.buffer[start:]
        first = buf.find(b",")
        second = buf.find(b",", first + 1) if first >= 0 else -1
        if second < 0:
            return self._skip(PACKET_ERROR) if _END.search(buf) else None
        length_text = buf[first + 1 : second]
        if not length_text.isdigit():
            return self._skip(PACKET_ERROR)
        end = second + 1 + int(length_text)
        early = _END.search(buf, second)
        if len(buf) < end + 6:  # ",*CS\r\n" not all here yet: wait, unless it ended early
            return self._skip(PACKET_ERROR) if early and early.start() < end else None
        tail = buf[end : end + 6]
        if tail[:2] != b",*" or tail[4:] != b"\r\n":
            return self._skip(PACKET_ERROR)
        self.buffer = buf[end + 6 :]
        try:
            sent_cs = int(tail[2:4], 16)
            header, data = buf[1:first].decode("ascii"), buf[second + 1 : end].decode("utf-8")
        except ValueError:
            return Received("", "", PACKET_ERROR)
        if sent_cs != checksum(buf[1 : end + 1]):
            return Received(header, data, CHECKSUM_ERROR)
        if header not in self.headers:
            return Received(header, data, HEADER_ERROR)
        return Received(header, data)


# --- TMscript, as far as this controller runs it -------------------------------------------

_CALL = re.compile(r"^\s*([A-Za-z_]\w*)\s*\((.*)\)\s*$", re.DOTALL)
_TOKEN = re.compile(
    r'\s*(?:(?P<num>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)|(?P<str>"[^"]*")'
    r"|(?P<bool>true|false)|(?P<punct>[{},]))"
)


def _tokens(text: str) -> list[tuple[str, str]] | None:
    tokens: list[tuple[str, str]] = []
    pos = 0
    while pos < len(text):
        match = _TOKEN.match(text, pos)
        if match is None or match.end() == pos:
            return None if text[pos:].strip() else tokens
        kind = match.lastgroup or ""
        tokens.append((kind, match.group(kind)))
        pos = match.end()
    return tokens


def _value(tokens: list[tuple[str, str]], pos: int) -> tuple[Arg, int] | None:
    """The value at `pos` and the position after it; None when there is none."""
    if pos >= len(tokens):
        return None
    kind, text = tokens[pos]
    if kind == "num":
        return float(text), pos + 1
    if kind == "str":
        return text[1:-1], pos + 1
    if kind == "bool":
        return text == "true", pos + 1
    if text != "{":
        return None
    return _array(tokens, pos + 1)


def _array(tokens: list[tuple[str, str]], pos: int) -> tuple[Arg, int] | None:
    """``{n, n, ...}`` from after its brace: the numbers and the position after ``}``."""
    items: list[float] = []
    if pos < len(tokens) and tokens[pos][1] == "}":
        return items, pos + 1
    while pos + 1 < len(tokens) and tokens[pos][0] == "num":
        items.append(float(tokens[pos][1]))
        if tokens[pos + 1][1] == "}":
            return items, pos + 2
        if tokens[pos + 1][1] != ",":
            return None
        pos += 2
    return None


def parse_call(line: str) -> tuple[str, list[Arg]] | None:
    """``Name(arg, ...)`` -> (name, args), numbers as floats, ``{..}`` as lists; None when the
    line is not such a call."""
    call = _CALL.match(line)
    if call is None:
        return None
    tokens = _tokens(call.group(2))
    if tokens is None:
        return None
    args: list[Arg] = []
    pos = 0
    while pos < len(tokens):
        parsed = _value(tokens, pos)
        if parsed is None:
            return None
        args.append(parsed[0])
        pos = parsed[1]
        if pos < len(tokens):
            if tokens[pos][1] != "," or pos + 1 == len(tokens):
                return None
            pos += 1
    return call.group(1), args


def _numbers(args: list[Arg]) -> list[float] | None:
    """The args when every one is a number (a bool is not)."""
    if all(isinstance(a, float) for a in args):
        return [a for a in args if isinstance(a, float)]
    return None


def _tcp_numbers(args: list[Arg]) -> list[float] | None:
    """ChangeTCP's numbers, X..RZ [, weight [, 9 inertia values]], however spelled: all
    spelled out (6, 7 or 16 numbers) or as ``{6}``, ``{6}, weight``, ``{6}, weight, {9}``."""
    flat = _numbers(args)
    if flat is not None:
        return flat if len(flat) in (6, 7, 16) else None
    first = args[0] if args else None
    if not isinstance(first, list) or len(first) != 6:
        return None
    if len(args) == 1:
        return list(first)
    weight = args[1]
    if not isinstance(weight, float):
        return None
    if len(args) == 2:
        return [*first, weight]
    inertia = args[2]
    if len(args) == 3 and isinstance(inertia, list) and len(inertia) == 9:
        return [*first, weight, *inertia]
    return None


def change_tcp(args: list[Arg], tcp_list: dict[str, Tcp]) -> tuple[str, Tcp] | None:
    """The TCP a ChangeTCP call names, with its name ("" for values); None if not valid."""
    if len(args) == 1 and isinstance(args[0], str):
        entry = tcp_list.get(args[0])
        return None if entry is None else (args[0], entry)
    numbers = _tcp_numbers(args)
    if numbers is None or (len(numbers) > 6 and numbers[6] < 0):
        return None
    mass = numbers[6] if len(numbers) > 6 else 0.0
    inertia = tuple(numbers[7:]) if len(numbers) == 16 else (0.0,) * 9
    return "", Tcp(f32(numbers[:6]), float(np.float32(mass)), f32(inertia))


def change_base(
    args: list[Arg], base_list: dict[str, tuple[float, ...]]
) -> tuple[str, tuple[float, ...]] | None:
    """The base a ChangeBase call names, with its name ("" for values); None if not valid."""
    if len(args) == 1 and isinstance(args[0], str):
        entry = base_list.get(args[0])
        return None if entry is None else (args[0], entry)
    numbers = _numbers(args)
    if numbers is None and len(args) == 1 and isinstance(args[0], list):
        numbers = args[0]
    if numbers is None or len(numbers) != 6:
        return None
    return "", f32(numbers)


# --- poses -----------------------------------------------------------------------------------


def tm_rotation(rx: float, ry: float, rz: float) -> Rotation:
    """Techman RX RY RZ (deg): R = Rz(RZ) Ry(RY) Rx(RX), scipy's extrinsic "xyz"."""
    return Rotation.from_euler("xyz", (rx, ry, rz), degrees=True)


def matrix(values: tuple[float, ...]) -> NDArray[np.float64]:
    """X Y Z RX RY RZ as a 4x4 matrix."""
    m = np.eye(4)
    m[:3, :3] = tm_rotation(*values[3:6]).as_matrix()
    m[:3, 3] = values[:3]
    return m


def values_of(m: NDArray[np.float64]) -> tuple[float, ...]:
    """A 4x4 matrix as X Y Z RX RY RZ."""
    angles = Rotation.from_matrix(m[:3, :3]).as_euler("xyz", degrees=True)
    return f32([*m[:3, 3], *angles])


def item_text(value: ItemValue, *, as_json: bool) -> str:
    """An item's value as the data table prints it (STRING or JSON)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value) if as_json else f'"{value}"'
    if isinstance(value, float):
        return f"{value:.6f}"
    inner = ",".join(f"{v:.6f}" for v in value)
    return f"[{inner}]" if as_json else f"{{{inner}}}"


# --- the controller ----------------------------------------------------------------------------


class TechmanSimulator(TcpSimulator):
    """TMflow's Listen Node and Ethernet Slave on an in-memory TM robot. `port` (and
    `ethernet_slave_port`) is the Ethernet Slave's; `listen_node_port` the Listen Node's."""

    name = "Techman TMflow"

    def __init__(self, *, broadcast_s: float | None = 0.1) -> None:
        super().__init__()
        self.broadcast_s = broadcast_s
        self.listen_node_port = 0
        self.listen_node_name = "Listen1"
        self._data_lock = threading.RLock()
        self.tcp_list: dict[str, Tcp] = {NO_TOOL: Tcp((0.0,) * 6)}
        #: the TCP list name the project starts with
        self.project_tcp = NO_TOOL
        self._tcp_name = NO_TOOL
        self._tcp = self.tcp_list[NO_TOOL]
        #: the base list (TMflow's bases: name -> X Y Z RX RY RZ in the robot base)
        self.base_list: dict[str, tuple[float, ...]] = {ROBOT_BASE: (0.0,) * 6}
        #: the base list name the project starts with
        self.project_base = ROBOT_BASE
        self._base_name = ROBOT_BASE
        self._base = self.base_list[ROBOT_BASE]
        self.project_running = True
        self.in_listen_node = True
        #: items checked in the Ethernet Slave's transmitted data table
        self.data_table: set[str] = set(ITEMS)
        #: seconds between a queued command's OK and its run (a robot finishing a motion)
        self.queue_delay_s = 0.0
        self._queue: list[tuple[float, Callable[[], None]]] = []
        self._tags: dict[int, float] = {}
        self._flange = matrix((400.0, 0.0, 600.0, 180.0, 0.0, 90.0))
        self.joints: list[float] = [0.0, 0.0, 90.0, 0.0, 90.0, 0.0]
        #: each read request finds the flange this many mm further along base x, J1 further
        self.moving_per_read = 0.0
        #: every script that reached the waiting node (run or refused), as (id, script)
        self.scripts: list[tuple[str, str]] = []
        #: every $TMSVR request's data
        self.svr_requests: list[str] = []
        self._node_lock = threading.Lock()
        self._node_listener: socket.socket | None = None
        self._node_conns: set[socket.socket] = set()
        self._svr_conns: set[socket.socket] = set()
        self._holder: socket.socket | None = None

    @property
    def ethernet_slave_port(self) -> int:
        return self.port

    def start(self) -> Self:
        super().start()
        if self.project_running:
            self._open_listen_node()
        return self

    def stop(self) -> None:
        super().stop()
        self._node_listener = None

    def _open_listen_node(self) -> None:
        self.listen_node_port = self.add_listener(self.listen_node_port, self.serve_listen_node)
        self._node_listener = self._listeners[-1]

    def _close_listen_node(self) -> None:
        listener, self._node_listener = self._node_listener, None
        if listener is not None:
            if listener in self._listeners:
                self._listeners.remove(listener)
            _close(listener)
        for conn in list(self._node_conns):
            _close(conn)

    # --- the flow and the pendant ------------------------------------------------------------

    def start_project(self, *, listen: bool = True) -> None:
        """The operator presses Play: the project sets its own TCP (`project_tcp`), opens
        the Listen node's server, and waits in the node when `listen`."""
        with self._data_lock:
            self._queue.clear()
            self._tcp_name, self._tcp = self.project_tcp, self.tcp_list[self.project_tcp]
            self._base_name = self.project_base
            self._base = self.base_list[self.project_base]
            self.project_running, self.in_listen_node = True, False
        if self._node_listener is None:
            self._open_listen_node()
        if listen:
            self.enter_listen_node()

    def stop_project(self) -> None:
        """The operator stops the project: the Listen node's server closes."""
        with self._data_lock:
            self.project_running = self.in_listen_node = False
        self._close_listen_node()

    def enter_listen_node(self) -> None:
        """The flow reaches the Listen node; a connected client hears of it."""
        with self._data_lock:
            self.in_listen_node = True
            holder = self._holder
        if holder is not None:
            with contextlib.suppress(OSError):
                holder.sendall(packet("TMSCT", f"0,{self.listen_node_name}"))

    def leave_listen_node(self) -> None:
        """The flow leaves the Listen node (scripts are refused with CPERR F1 from now)."""
        with self._data_lock:
            self.in_listen_node = False

    def add_tcp(self, name: str, values: tuple[float, ...], mass: float = 0.0) -> None:
        """A TCP taught into the TCP list (TMflow's tool list)."""
        with self._data_lock:
            self.tcp_list[name] = Tcp(f32(values), float(np.float32(mass)))

    def add_base(self, name: str, values: tuple[float, ...]) -> None:
        """A base taught into the base list (in the robot base)."""
        with self._data_lock:
            self.base_list[name] = f32(values)

    def select_base(self, name: str) -> None:
        """The flow or the operator sets a base of the list as the current base."""
        with self._data_lock:
            self._base_name, self._base = name, self.base_list[name]

    def current_base(self) -> tuple[str, tuple[float, ...]]:
        """The base's name ("" when set by values) and its values, now."""
        with self._data_lock:
            self._settle()
            return self._base_name, self._base

    def select_tcp(self, name: str) -> None:
        """The flow or the operator sets a TCP of the list as the current TCP."""
        with self._data_lock:
            self._tcp_name, self._tcp = name, self.tcp_list[name]

    def set_current_tcp(self, values: tuple[float, ...], mass: float = 0.0) -> None:
        """The project's own ChangeTCP by values (a SET node of the flow)."""
        with self._data_lock:
            self._tcp_name, self._tcp = "", Tcp(f32(values), float(np.float32(mass)))

    def current_tcp(self) -> tuple[str, Tcp]:
        """The TCP's name ("" when set by values) and the TCP the robot moves by now."""
        with self._data_lock:
            self._settle()
            return self._tcp_name, self._tcp

    def set_flange(self, position_mm: tuple[float, ...], rotation: NDArray[np.float64]) -> None:
        """The robot jogged: its flange at `position_mm` with the 3x3 `rotation`, in the robot
        base."""
        m = np.eye(4)
        m[:3, :3] = Rotation.from_matrix(rotation).as_matrix()
        m[:3, 3] = position_mm
        with self._data_lock:
            self._flange = m

    def jog_flange(self, *values: float) -> None:
        """The flange at X Y Z (mm) RX RY RZ (deg) in the robot base."""
        with self._data_lock:
            self._flange = matrix(tuple(values))

    def flange(self) -> NDArray[np.float64]:
        """The flange in the robot base, 4x4 (mm)."""
        with self._data_lock:
            return self._flange.copy()

    def set_joints(self, *degrees: float) -> None:
        with self._data_lock:
            self.joints = [float(v) for v in degrees]

    def listen_node_clients(self) -> int:
        """Connections open on the Listen node (the one served and any waiting)."""
        return len(self._node_conns)

    def ethernet_slave_clients(self) -> int:
        return len(self._svr_conns)

    # --- the queue -------------------------------------------------------------------------

    def _enqueue(self, action: Callable[[], None]) -> float:
        due = time.monotonic() + self.queue_delay_s
        self._queue.append((due, action))
        return due

    def _settle(self) -> None:
        """Run every queued command whose time has come, in order."""
        now = time.monotonic()
        while self._queue and self._queue[0][0] <= now:
            self._queue.pop(0)[1]()

    # --- the Listen Node -----------------------------------------------------------------

    def serve_listen_node(self, conn: socket.socket) -> None:
        self._node_conns.add(conn)
        try:
            while not self._node_lock.acquire(timeout=0.05):
                if conn not in self._connections:
                    return  # closed while it waited (the project stopped, the robot off)
            try:
                self._holder = conn
                self._converse(conn, LISTEN_NODE_HEADERS, self._listen_node_reply, None)
            finally:
                self._holder = None
                self._node_lock.release()
        finally:
            self._node_conns.discard(conn)

    def _converse(
        self,
        conn: socket.socket,
        headers: tuple[str, ...],
        answer: Callable[[Received], bytes | None],
        send_lock: threading.Lock | None,
    ) -> None:
        reader = PacketReader(headers)
        while chunk := conn.recv(65536):
            for received in reader.feed(chunk):
                if self.stalled:
                    continue
                reply = answer(received)
                if reply is None or self.stalled:
                    continue
                self.slow()
                with send_lock or contextlib.nullcontext():
                    conn.sendall(reply)

    def _listen_node_reply(self, received: Received) -> bytes | None:
        if received.error is not None:
            return packet("CPERR", received.error)
        if received.header == "TMSTA":
            return self._tmsta(received.data)
        with self._data_lock:
            listening = self.in_listen_node
        if not listening:
            return packet("CPERR", NOT_IN_LISTEN_NODE)
        return self._tmsct(received.data)

    def _tmsta(self, data: str) -> bytes | None:
        code, _, rest = data.partition(",")
        if self.fault_at(f"TMSTA {code}") is not None:
            return None
        with self._data_lock:
            self._settle()
            if code == "00" and rest == "":
                if self.in_listen_node:
                    return packet("TMSTA", f"00,true,{self.listen_node_name}")
                return packet("TMSTA", "00,false,")
            if code == "01" and rest.isdigit():
                due = self._tags.get(int(rest))
                state = "none" if due is None else str(due <= time.monotonic()).lower()
                return packet("TMSTA", f"01,{int(rest):02d},{state}")
        return packet("CPERR", DATA_ERROR)

    def _tmsct(self, data: str) -> bytes | None:
        script_id, comma, script = data.partition(",")
        if not comma or not script_id:
            return packet("CPERR", DATA_ERROR)
        self.scripts.append((script_id, script))
        calls = [
            ("", []) if not line.strip() else parse_call(line) for line in script.split("\r\n")
        ]
        with self._data_lock:
            actions = [self._action(call) for call in calls]
        errors = [str(n) for n, action in enumerate(actions, 1) if action is None]
        if errors:
            return packet("TMSCT", f"{script_id},ERROR;{';'.join(errors)}")
        stop = None
        for call in calls:
            if call is not None and call[0] and (stop := self.fault_at(call[0])) is not None:
                break
        if stop == "before":
            return None
        with self._data_lock:
            for action in actions:
                if action is not None:
                    action()
            self._settle()
        if stop == "after":
            self.stalled = True
            return None
        return packet("TMSCT", f"{script_id},OK")

    def _action(self, call: tuple[str, list[Arg]] | None) -> Callable[[], None] | None:
        """What a valid line does (run when the whole script is valid), None for a line in
        error."""
        if call is None:
            return None
        name, args = call
        if name == "":
            return lambda: None
        if name == "ChangeBase":
            base = change_base(args, self.base_list)
            return None if base is None else lambda: self._queue_base(*base)
        if name == "ChangeTCP":
            tcp = change_tcp(args, self.tcp_list)
            return None if tcp is None else lambda: self._queue_tcp(*tcp)
        if name == "QueueTag":
            numbers = _numbers(args)
            if numbers is None or len(numbers) not in (1, 2) or numbers[0] not in range(1, 16):
                return None
            tag = int(numbers[0])
            return lambda: self._queue_tag(tag)
        if name == "ScriptExit" and not args:
            return self.leave_listen_node
        return None

    def _queue_tcp(self, name: str, tcp: Tcp) -> None:
        def run() -> None:
            self._tcp_name, self._tcp = name, tcp

        self._enqueue(run)

    def _queue_base(self, name: str, values: tuple[float, ...]) -> None:
        def run() -> None:
            self._base_name, self._base = name, values

        self._enqueue(run)

    def _queue_tag(self, tag: int) -> None:
        self._tags[tag] = self._enqueue(lambda: None)

    # --- the Ethernet Slave ------------------------------------------------------------------

    def serve(self, conn: socket.socket) -> None:
        """The Ethernet Slave: requests answered, the data table broadcast."""
        self._svr_conns.add(conn)
        send_lock = threading.Lock()
        done = threading.Event()
        if self.broadcast_s:
            self._spawn(self._broadcast, conn, send_lock, done)
        try:
            self._converse(conn, ETHERNET_SLAVE_HEADERS, self._svr_reply, send_lock)
        finally:
            done.set()
            self._svr_conns.discard(conn)

    def _broadcast(
        self, conn: socket.socket, send_lock: threading.Lock, done: threading.Event
    ) -> None:
        interval = self.broadcast_s or 0.1
        while not done.wait(interval):
            if self.stalled:
                continue
            with self._data_lock:
                items = self._items(move=False)
            lines = "\r\n".join(f"{k}={item_text(v, as_json=False)}" for k, v in items.items())
            try:
                with send_lock:
                    conn.sendall(packet("TMSVR", f"{BROADCAST_ID},2,{lines}"))
            except OSError:
                return

    def _svr_reply(self, received: Received) -> bytes | None:
        if received.error is not None:
            return packet("CPERR", received.error)
        self.svr_requests.append(received.data)
        parts = received.data.split(",", 2)
        if len(parts) < 3 or not parts[0] or not parts[1].isdigit():
            return packet("CPERR", DATA_ERROR)
        tid, mode, content = parts[0], int(parts[1]), parts[2]
        stop = self.fault_at(f"TMSVR {mode}")
        if stop == "before":
            return None
        reply = self._svr_answer(mode, content)
        if stop == "after":
            self.stalled = True
            return None
        return packet("TMSVR", f"{tid},{reply}")

    def _svr_answer(self, mode: int, content: str) -> str:
        """The reply after the transaction ID: ``MODE,CONTENT`` or ``0,CODE,DESCRIPTION``."""
        if mode in (12, 13):
            names = _read_names(content, as_json=mode == 13)
            if names is None:
                return _status(SVR_INVALID_DATA)
            missing = [n for n in names if n not in self.data_table or n not in ITEMS]
            if missing:
                return _status(SVR_NOT_EXIST, missing[0])
            with self._data_lock:
                items = self._items(move=True)
            if mode == 12:
                return "12," + "\r\n".join(
                    f"{n}={item_text(items[n], as_json=False)}" for n in names
                )
            pairs = ",".join(
                f'{{"Item":{json.dumps(n)},"Value":{item_text(items[n], as_json=True)}}}'
                for n in names
            )
            return f"13,[{pairs}]"
        if mode in (2, 3):
            names = _written_names(content, as_json=mode == 3)
            if names is None:
                return _status(SVR_INVALID_DATA)
            missing = [n for n in names if n not in ITEMS]
            return (
                _status(SVR_NOT_EXIST, missing[0]) if missing else _status(SVR_READ_ONLY, names[0])
            )
        return _status(SVR_NOT_SUPPORTED)

    def _items(self, *, move: bool) -> dict[str, ItemValue]:
        """Every item of the data table, now (the robot moved once when `move`)."""
        self._settle()
        if move and self.moving_per_read:
            self._flange[0, 3] += self.moving_per_read
            self.joints[0] += self.moving_per_read
        tool_m = self._flange @ matrix(self._tcp.values)
        flange, tool = values_of(self._flange), values_of(tool_m)
        in_base = np.linalg.inv(matrix(self._base))
        return {
            "Robot_Error": False,
            "Project_Run": self.project_running,
            "Project_Pause": False,
            "Joint_Angle": f32(self.joints),
            "Coord_Robot_Flange": flange,
            "Coord_Robot_Tool": tool,
            "Coord_Base_Flange": values_of(in_base @ self._flange),
            "Coord_Base_Tool": values_of(in_base @ tool_m),
            "TCP_Name": self._tcp_name,
            "TCP_Value": self._tcp.values,
            "TCP_Mass": self._tcp.mass,
            "Base_Name": self._base_name,
            "Base_Value": self._base,
        }


def _status(status: tuple[str, str], data: str | None = None) -> str:
    code, description = status
    return f"0,{code},{description}" + ("" if data is None else f";{data}")


def _read_names(content: str, *, as_json: bool) -> list[str] | None:
    """The items a read request names (STRING: one a line; JSON: [{"Item": name}, ...])."""
    if not as_json:
        names = [n.strip() for n in content.split("\r\n")]
        return names if names and all(names) else None
    try:
        request = json.loads(content)
    except ValueError:
        return None
    if not isinstance(request, list) or not request:
        return None
    items: list[object] = [r.get("Item") if isinstance(r, dict) else None for r in request]
    found = [n for n in items if isinstance(n, str)]
    return found if len(found) == len(items) else None


def _written_names(content: str, *, as_json: bool) -> list[str] | None:
    """The items a write names (STRING: Item=Value lines; JSON: [{"Item", "Value"}, ...])."""
    if not as_json:
        lines = content.split("\r\n")
        if not all("=" in line for line in lines):
            return None
        return [line.split("=", 1)[0].strip() for line in lines]
    return _read_names(content, as_json=True)


def _close(sock: socket.socket) -> None:
    with contextlib.suppress(OSError):
        sock.shutdown(socket.SHUT_RDWR)
    sock.close()


def exchange(port: int, data: bytes, *, replies: int = 1, timeout_s: float = 2.0) -> list[bytes]:
    """Send `data` to 127.0.0.1:`port` and return the first `replies` packets that come back
    (fewer when the controller is silent for `timeout_s`): a test's look at the wire."""
    found: list[bytes] = []
    buffer = b""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout_s) as sock:
        sock.sendall(data)
        while len(found) < replies:
            try:
                chunk = sock.recv(65536)
            except TimeoutError:
                break
            if not chunk:
                break
            buffer += chunk
            while (end := _END.search(buffer)) is not None:
                found.append(buffer[: end.end()])
                buffer = buffer[end.end() :]
    return found[:replies]
