"""Techman TM robots (TMflow): the current TCP, written through the Listen Node and read
through the Ethernet Slave.

Followed: Techman's *Expression Editor and Listen Node* manual (I848 editions for TMflow
1.76-1.84, chapter "Listen Node") and the *Software Manual TMflow*, appendix "Ethernet Slave"
(the data table), as Techman's own driver reads them (TechmanRobotInc/tmr_ros2
``tm_driver``: ``tm_packet.cpp`` for the framing, ``tm_svr_communication.cpp`` for the data
table's answers) and techmanpy (PyPI) writes them. Every packet is
``$HEADER,LENGTH,DATA,*CS\\r\\n``: LENGTH the byte count of DATA, CS the XOR of the bytes from
the header to the comma after DATA in two hexadecimal digits.

What is written where: the robot's one current TCP, by value. ``$TMSCT`` to the Listen Node
(TCP 5890, a server the running project's Listen node opens) carries the script
``ChangeTCP({X,Y,Z,RX,RY,RZ},mass,{Ixx,Iyy,Izz,X,Y,Z,RX,RY,RZ})`` and ``QueueTag(15,0)``:
X Y Z mm and RX RY RZ deg about the fixed axes, R = Rz(RZ) Ry(RY) Rx(RX) (as `fanuc_wpr`;
tm_driver composes them with ``setRPY``); the mass in kg and, when tcpcal knows the tool's
load, its centre of gravity as the mass centre frame's X Y Z (inertia moments 0, a point
mass). Without a load in tcpcal the mass the controller holds (``TCP_Mass``) is written back,
so the write changes the frame only. The Listen Node answers ``ID,OK`` once it accepted the
script (``ERROR;n`` names a line it refused, ``$CPERR,2,F1`` says the project is not waiting
in its Listen node); ChangeTCP then runs in the motion queue, in order, so the connector asks
``$TMSTA 01,15`` until the queue tag is reached before anything reads the TCP back. A script
never ends the node: ``ScriptExit()`` would send the project on through its flow, so it is
not sent.

What is read, from the Ethernet Slave (TCP 5891): ``$TMSVR`` mode 12 (STRING) requests of the
data table's items, answered in mode 12 with ``Item=Value`` lines (tm_driver's READ_STRING;
mode 2 is read the same way); answers are matched by their transaction ID, and whatever
else arrives (the data table's unasked broadcast) is passed by. ``TCP_Value`` is the current
TCP in the flange frame (read-only), ``TCP_Name`` its name in the TCP list (empty when it was
set by values), ``TCP_Mass``; ``Coord_Robot_Flange`` the flange in the robot base and
``Joint_Angle`` J1-J6 (deg), asked for in the same request as the TCP, so they describe one
moment. A mode 0 answer ``04,NotExist;<item>`` means the item is not in the Ethernet Slave's
data table: the refusal says which to add.

What persists (contract v1.3, scope "live"): the TCP holds for the running project only. The
TCP list stored on the robot is untouched, and the next start of a project sets the TCP the
project was written with; the reconcile rounds then show what the robot moves by.

Frames (contract v1.4 "Frames at the controller"): the robot's current base, by value,
written as the TCP is: ``ChangeBase({X,Y,Z,RX,RY,RZ})`` (the Listen Node manual's function
list: the base in the robot base, X Y Z mm, RX RY RZ deg as for ChangeTCP) and the queue tag,
waited for the same way, then read back from the Ethernet Slave's ``Base_Value`` (the current
base in the robot base, read-only) with ``Base_Name`` (its name in the base list, empty when
set by values). Like the TCP it holds for the running project only (scope "live": a project
start sets its own base); the base list is untouched. A fixed tool has no place here: the
Listen Node's functions change the current base and the TCP on the flange, none a
stationary tool. The pose read asks for ``Base_Name`` and ``Base_Value`` in its one request
(the frame the robot moves in); an Ethernet Slave whose data table has not the two is asked
again without them, and the live frame is then unread.

A session keeps to one deadline from `connect` (the Ethernet Slave's connection, the Listen
Node's, each request and answer, the wait for the queue tag). The Listen Node is connected to
only when a write needs it, so reading needs no project running. A Listen node serves its
client until that client leaves, so `close` always closes both connections, whatever
happened before: nothing is left holding the node for the next attempt.
"""

from __future__ import annotations

import itertools
import math
import re
import socket
import time

import numpy as np

from app.kinematics.poses import fanuc_wpr_from_quaternion_wxyz, quaternion_wxyz_from_fanuc_wpr
from app.vendors.connector import (
    UNREAD_FRAME,
    ClosingSession,
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
from app.vendors.sockets import close_quietly, open_connection, recv_some, send_all
from app.vendors.techman import TMFLOW
from app.vendors.tool import ToolData, finite_tool_data

LISTEN_NODE, ETHERNET_SLAVE = "listen_node", "ethernet_slave"
#: The queue tag a write waits for (1-15, the manual's range).
QUEUE_TAG = 15
#: What read_pose asks for, in one request.
POSE_ITEMS = ("Coord_Robot_Flange", "Joint_Angle", "TCP_Value", "TCP_Name", "TCP_Mass")
#: The current base, asked for with the pose where the data table has it.
BASE_ITEMS = ("Base_Name", "Base_Value")
#: $CPERR codes (the Listen Node manual's table).
CPERR_WORDS = {
    "01": "packet error",
    "02": "checksum error",
    "03": "header error",
    "04": "packet data error",
    "F1": "the project is not waiting in its Listen node",
}
#: $TMSVR mode 0 codes (the Ethernet Slave's answers).
SVR_WORDS = {
    "01": "NotSupport",
    "02": "WritePermission",
    "03": "InvalidData",
    "04": "NotExist",
    "05": "ReadOnly",
    "06": "ModeError",
    "07": "ValueError",
}
REMEDY_NO_PROJECT = (
    "start a project on the robot (TMflow: Play) whose flow waits in a Listen node, then "
    "deploy again"
)
REMEDY_NOT_LISTENING = (
    "let the running project's flow reach its Listen node (the Listen node waits for "
    "scripts only while the flow is in it), then deploy again"
)
_POLL_S = 0.02
_END = re.compile(rb"\*[0-9A-Fa-f]{2}\r\n")
_HEAD = re.compile(rb"\$([A-Z]+),(\d+),")


def checksum(body: bytes) -> int:
    """The XOR of every byte of `body`."""
    value = 0
    for byte in body:
        value ^= byte
    return value


def encode_packet(header: str, data: str) -> bytes:
    """``$HEADER,LENGTH,DATA,*CS\\r\\n``."""
    payload = data.encode("utf-8")
    body = f"{header},{len(payload)},".encode("ascii") + payload + b","
    return b"$" + body + b"*" + f"{checksum(body):02X}".encode("ascii") + b"\r\n"


def number_text(value: float) -> str:
    """A number as the script carries it: six decimals, never an exponent, no -0."""
    if not math.isfinite(value):
        raise ValueError(f"{value} cannot be sent to the controller")
    text = f"{value:.6f}"
    return "0.000000" if text == "-0.000000" else text


def tm_values(data: ToolData | Frame) -> tuple[float, ...]:
    """X, Y, Z (mm), RX, RY, RZ (deg) of a tool frame or a base."""
    rx, ry, rz = (float(v) for v in fanuc_wpr_from_quaternion_wxyz(np.asarray(data.quaternion)))
    return (*(float(v) for v in data.position_mm), rx, ry, rz)


def tm_frame(values: tuple[float, ...]) -> Frame:
    """X, Y, Z, RX, RY, RZ (mm, deg) as a Frame."""
    q = quaternion_wxyz_from_fanuc_wpr(values[3:6])
    return Frame(
        (values[0], values[1], values[2]), (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
    )


def change_tcp_script(values: tuple[float, ...], mass: float, cog: tuple[float, ...] | None) -> str:
    """``ChangeTCP({X,Y,Z,RX,RY,RZ},mass[,{0,0,0,cx,cy,cz,0,0,0}])`` then the queue tag."""
    frame = ",".join(number_text(v) for v in values)
    call = f"ChangeTCP({{{frame}}},{number_text(mass)}"
    if cog is not None:
        inertia = ",".join(number_text(v) for v in (0.0, 0.0, 0.0, *cog, 0.0, 0.0, 0.0))
        call += f",{{{inertia}}}"
    return f"{call})\r\nQueueTag({QUEUE_TAG},0)"


def change_base_script(values: tuple[float, ...]) -> str:
    """``ChangeBase({X,Y,Z,RX,RY,RZ})`` then the queue tag."""
    frame = ",".join(number_text(v) for v in values)
    return f"ChangeBase({{{frame}}})\r\nQueueTag({QUEUE_TAG},0)"


def parse_value(text: str) -> float | str | bool | tuple[float, ...]:
    """An item's value as the data table prints it in STRING format: ``{a,b,..}`` numbers,
    ``"text"``, ``true``/``false``, or a number; ValueError when it is none of them."""
    text = text.strip()
    if text.startswith("{") and text.endswith("}"):
        values = tuple(float(v) for v in text[1:-1].split(",")) if text[1:-1].strip() else ()
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"{text} holds a value that is not a finite number")
        return values
    if len(text) >= 2 and text[0] == text[-1] == '"':
        return text[1:-1]
    if text in ("true", "false"):
        return text == "true"
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is not a finite number")
    return value


class _Channel:
    """One connection speaking $-packets: send one, read the next whole one."""

    def __init__(self, sock: socket.socket, peer: str) -> None:
        self.sock = sock
        self.peer = peer
        self.buffer = bytearray()

    def send(self, header: str, data: str, deadline: Deadline) -> None:
        send_all(self.sock, encode_packet(header, data), deadline, peer=self.peer)

    def receive(self, deadline: Deadline) -> tuple[str, str]:
        """The next packet's header and data; ControllerProtocolError for one that is not a
        packet or whose checksum is wrong."""
        while (packet := self._cut()) is None:
            if len(self.buffer) > 1 << 20:
                raise ControllerUnreachable(f"{self.peer} sent 1 MiB without a packet end")
            self.buffer.extend(recv_some(self.sock, deadline, peer=self.peer))
        return packet

    def _cut(self) -> tuple[str, str] | None:
        start = self.buffer.find(b"$")
        if start < 0:
            self.buffer.clear()
            return None
        del self.buffer[:start]
        head = _HEAD.match(self.buffer)
        if head is None:
            if _END.search(self.buffer) is not None or len(self.buffer) > 64:
                raise ControllerProtocolError(f"{self.peer} sent {bytes(self.buffer[:80])!r}")
            return None
        # (the match reads the buffer it was made on: everything taken before it changes)
        header, start, end = head.group(1), head.end(), head.end() + int(head.group(2))
        if len(self.buffer) < end + 6:
            return None
        raw = bytes(self.buffer[: end + 6])
        del self.buffer[: end + 6]
        if raw[end : end + 2] != b",*" or raw[end + 4 :] != b"\r\n":
            raise ControllerProtocolError(f"{self.peer} sent {raw[:80]!r}: not a packet")
        if int(raw[end + 2 : end + 4], 16) != checksum(raw[1 : end + 1]):
            raise ControllerProtocolError(f"{self.peer} sent {raw[:80]!r}: wrong checksum")
        try:
            return header.decode("ascii"), raw[start:end].decode("utf-8")
        except UnicodeDecodeError as err:
            raise ControllerProtocolError(f"{self.peer} sent {raw[:80]!r}: not text") from err


class TechmanConnector(ClosingSession):
    """A session with a TM robot's TMflow: the current TCP, the flange and the joints."""

    protocol = "techman"

    def __init__(self, settings: ControllerSettings) -> None:
        self._settings = settings
        #: the whole session's time budget, from here: both connections, every request
        self._deadline = Deadline(settings.timeout_s)
        self._ids = itertools.count(1)
        self._node: _Channel | None = None
        port = TMFLOW.port_of(settings, ETHERNET_SLAVE)
        peer = f"TMflow Ethernet Slave at {settings.host}:{port}"
        self._slave = _Channel(open_connection(settings.host, port, self._deadline), peer)

    # --- the Connector interface -----------------------------------------------------------

    def describe(self, target: ToolTarget) -> str:
        """``current TCP``: every tool of the robot is written to its one live TCP."""
        return TMFLOW.describe(target)

    def read_tool(self, target: ToolTarget) -> ToolData:
        """The current TCP (``TCP_Value``); no load (the mass centre is not read)."""
        TMFLOW.check(target)
        items, _ = self._read_items(("TCP_Value",))
        frame = tm_frame(self._six(items, "TCP_Value"))
        return ToolData(position_mm=frame.position_mm, quaternion=frame.quaternion, load=None)

    def write_tool(self, target: ToolTarget, data: ToolData) -> None:
        """ChangeTCP through the Listen Node, then wait until the queue ran it."""
        TMFLOW.check(target)
        finite_tool_data(data)
        if data.load is not None:
            mass, cog = data.load.mass_kg, data.load.cog_mm
        else:
            items, _ = self._read_items(("TCP_Mass",))
            mass, cog = self._number(items, "TCP_Mass"), None
        self._run_queued(change_tcp_script(tm_values(data), mass, cog))

    def _run_queued(self, script: str) -> None:
        """Send `script` to the Listen Node, then wait until the queue ran it."""
        node = self._listen_node()
        script_id = f"tcpcal{next(self._ids)}"
        # From here the script may reach the robot, whether or not its answer does.
        with write_sent():
            node.send("TMSCT", f"{script_id},{script}", self._deadline)
            self._await_script(node, script_id, script)
            self._await_tag(node)

    def describe_frame(self, target: FrameTarget) -> str:
        """``current base``: every base of the robot is written to its one current base."""
        self._check_frame(target)
        return TMFLOW.describe_frame(target)

    def read_frame(self, target: FrameTarget) -> Frame:
        """The current base (``Base_Value``, in the robot base)."""
        self._check_frame(target)
        items, _ = self._read_items(("Base_Value",))
        return tm_frame(self._six(items, "Base_Value"))

    def write_frame(self, target: FrameTarget, frame: Frame) -> None:
        """ChangeBase through the Listen Node, then wait until the queue ran it."""
        self._check_frame(target)
        finite_frame(frame)
        self._run_queued(change_base_script(tm_values(frame)))

    def _check_frame(self, target: FrameTarget) -> None:
        if target.kind == "fixed_tool":
            raise ValueError(
                "a techman controller has no stationary tool tcpcal can write: the Listen "
                "Node's functions change the current base (ChangeBase) and the TCP on the "
                "flange (ChangeTCP); make the frame a base"
            )

    def read_pose(self) -> PoseReading:
        """The flange in the robot base (``Coord_Robot_Flange``), J1-J6 (``Joint_Angle``),
        the current TCP and the current base (``Base_Name``, ``Base_Value``), read in one
        request; each item's text as the robot printed it."""
        live_frame = UNREAD_FRAME
        try:
            items, readings = self._read_items(POSE_ITEMS + BASE_ITEMS)
        except ControllerRefused as err:
            if not err.controller_message.endswith(tuple(f";{n}" for n in BASE_ITEMS)):
                raise
            items, readings = self._read_items(POSE_ITEMS)  # no base items in the table
        else:
            name = items["Base_Name"]
            live_frame = LiveFrame(
                number=None,
                name=name if isinstance(name, str) and name else None,
                frame=tm_frame(self._six(items, "Base_Value")),
            )
        joints = items.get("Joint_Angle")
        if not isinstance(joints, tuple) or len(joints) < 6:
            raise ControllerProtocolError(f"{self._slave.peer}: Joint_Angle is {joints!r}")
        return PoseReading(
            flange=tm_frame(self._six(items, "Coord_Robot_Flange")),
            joints_deg=joints[:6],
            live_tool=LiveTool(number=None, frame=tm_frame(self._six(items, "TCP_Value"))),
            readings=readings,
            live_frame=live_frame,
        )

    def close(self) -> None:
        """Close both connections (the Listen node is free for the next client); never
        raises. Nothing is sent: ScriptExit would move the project on."""
        close_quietly(self._slave.sock)
        if self._node is not None:
            close_quietly(self._node.sock)
            self._node = None

    # --- the Ethernet Slave ------------------------------------------------------------------

    def _read_items(
        self, names: tuple[str, ...]
    ) -> tuple[dict[str, float | str | bool | tuple[float, ...]], dict[str, str]]:
        """The items' values and their texts as printed, from one mode 12 request."""
        tid = f"tcpcal{next(self._ids)}"
        self._slave.send("TMSVR", f"{tid},12," + "\r\n".join(names), self._deadline)
        mode, content = self._svr_answer(tid)
        if mode == "0":
            raise self._svr_refusal(content)
        if mode not in ("12", "2"):
            raise ControllerProtocolError(f"{self._slave.peer} answered mode {mode}: {content!r}")
        texts: dict[str, str] = {}
        for line in content.split("\r\n"):
            name, equals, value = line.partition("=")
            if equals:
                texts[name.strip()] = value.strip()
        missing = [n for n in names if n not in texts]
        if missing:
            raise ControllerProtocolError(f"{self._slave.peer} left out {', '.join(missing)}")
        values = {}
        for name in names:
            try:
                values[name] = parse_value(texts[name])
            except ValueError as err:
                raise ControllerProtocolError(
                    f"{self._slave.peer}: {name}={texts[name]!r}: {err}"
                ) from err
        return values, {name: texts[name] for name in names}

    def _svr_answer(self, tid: str) -> tuple[str, str]:
        """Mode and content of the answer to transaction `tid` (other packets passed by)."""
        while True:
            header, data = self._slave.receive(self._deadline)
            if header == "CPERR":
                words = CPERR_WORDS.get(data, data)
                raise ControllerProtocolError(f"{self._slave.peer} answered $CPERR {data}: {words}")
            parts = data.split(",", 2)
            if header == "TMSVR" and len(parts) == 3 and parts[0] == tid:
                return parts[1], parts[2]

    def _svr_refusal(self, content: str) -> ControllerRefused:
        code, _, rest = content.partition(",")
        words, _, item = rest.partition(";")
        message = f"{code},{rest}"
        if code == "04" and item:
            return ControllerRefused(
                f"the robot's Ethernet Slave does not serve {item} ({message})",
                controller_message=message,
                remedy=(
                    f"add {item} to the Ethernet Slave's data table (the items it transmits) "
                    "in TMflow's Ethernet Slave settings, and enable the Ethernet Slave"
                ),
            )
        return ControllerRefused(
            f"the robot's Ethernet Slave refused the read: {SVR_WORDS.get(code, words)} "
            f"({message})",
            controller_message=message,
        )

    def _six(
        self, items: dict[str, float | str | bool | tuple[float, ...]], name: str
    ) -> tuple[float, ...]:
        value = items[name]
        if not isinstance(value, tuple) or len(value) != 6:
            raise ControllerProtocolError(f"{self._slave.peer}: {name} is {value!r}, not 6 numbers")
        return value

    def _number(self, items: dict[str, float | str | bool | tuple[float, ...]], name: str) -> float:
        value = items[name]
        if not isinstance(value, float) or value < 0:
            raise ControllerProtocolError(f"{self._slave.peer}: {name} is {value!r}")
        return value

    # --- the Listen Node ---------------------------------------------------------------------

    def _listen_node(self) -> _Channel:
        """The Listen Node's connection (opened on first use). A connection refused while
        the Ethernet Slave answers is a robot with no project running: a refusal saying so."""
        if self._node is not None:
            return self._node
        host, port = self._settings.host, TMFLOW.port_of(self._settings, LISTEN_NODE)
        try:
            sock = open_connection(host, port, self._deadline)
        except ControllerUnreachable as err:
            if not isinstance(err.__cause__, ConnectionRefusedError):
                raise
            state = self._why_no_listen_node()
            raise ControllerRefused(
                f"the robot refused a connection to its Listen Node at {host}:{port}: {state}",
                controller_message=f"connection refused ({state})",
                remedy=REMEDY_NO_PROJECT,
            ) from err
        self._node = _Channel(sock, f"TMflow Listen Node at {host}:{port}")
        return self._node

    def _why_no_listen_node(self) -> str:
        """Why nothing listens on the Listen Node's port, as far as the data table tells."""
        try:
            running = self._read_items(("Project_Run",))[0]["Project_Run"]
        except ControllerRefused:  # Project_Run not in the Ethernet Slave's data table
            return "no project is running, or the running one has no Listen node"
        if running is False:
            return "no project is running"
        return "the running project has no Listen node listening"

    def _node_packet(self, node: _Channel, wanted: str) -> str:
        """The data of the next `wanted` packet ($TMSCT or $TMSTA) on the Listen Node; a
        $CPERR is raised as what it says."""
        while True:
            try:
                header, data = node.receive(self._deadline)
            except ControllerUnreachable as err:
                raise ControllerUnreachable(
                    f"{err} (a Listen node serves one client at a time: another client "
                    "connected to it may hold it)"
                ) from err
            if header == "CPERR":
                words = CPERR_WORDS.get(data, "unknown error")
                if data == "F1":
                    raise ControllerRefused(
                        f"the robot did not take the script: {words} ($CPERR {data})",
                        controller_message=f"$CPERR {data}: {words}",
                        remedy=REMEDY_NOT_LISTENING,
                    )
                raise ControllerProtocolError(f"{node.peer} answered $CPERR {data}: {words}")
            if header == wanted:
                return data

    def _await_script(self, node: _Channel, script_id: str, script: str) -> None:
        """Wait for the script's ``ID,OK`` (warnings allowed); ``ERROR;n`` is a refusal."""
        while True:
            answer_id, _, answer = self._node_packet(node, "TMSCT").partition(",")
            if answer_id == script_id:
                break  # another ID: the node's own news (ID 0, entering it): passed by
        status, _, lines = answer.partition(";")
        if status == "OK":
            return
        if status != "ERROR":
            raise ControllerProtocolError(f"{node.peer} answered the script with {answer!r}")
        refused = [script.split("\r\n")[int(n) - 1] for n in lines.split(";") if n.isdigit()]
        refused = [line for line in refused if line] or [script]
        raise ControllerRefused(
            f"the robot's Listen node refused {'; '.join(refused)}",
            controller_message=f"{script_id},{answer}",
        )

    def _await_tag(self, node: _Channel) -> None:
        """Ask ``$TMSTA 01,<tag>`` until the queue reached the tag (ChangeTCP ran)."""
        while True:
            node.send("TMSTA", f"01,{QUEUE_TAG:02d}", self._deadline)
            while True:
                code, _, rest = self._node_packet(node, "TMSTA").partition(",")
                if code == "01":
                    break
            tag, _, state = rest.partition(",")
            if not tag.isdigit() or int(tag) != QUEUE_TAG:
                continue
            if state == "true":
                return
            if state != "false":
                raise ControllerProtocolError(
                    f"{node.peer}: queue tag {QUEUE_TAG}, just queued, is {state!r}"
                )
            time.sleep(min(_POLL_S, self._deadline.remaining()))
