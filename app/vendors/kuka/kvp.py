"""KUKA KRC tool data over KUKAVARPROXY (the OpenShowVar protocol, TCP 7000).

Followed: KUKAVARPROXY's own source, ImtsSrl/KUKAVARPROXY ``src/basMain.bas``
(``readMsg``: the reply body) and ``src/frmMain.frm`` (``sockServer_Read``: the framing,
several messages per read), checked against the client py-openshowvar (PyPI) and
ImtsSrl/openshowvar. All integers are big-endian 16-bit words:

    request  = msg_id, length, mode (1 byte: 0 read, 1 write), name_len, name
               [, value_len, value]           length = bytes after the length word
    reply    = msg_id, length, mode, value_len, value, 0x00 0x01, ok (1 byte: 1 or 0)

The proxy answers each request with the request's message id. A read the KRC cannot
resolve (unknown variable, index out of range) comes back as an empty value; a write the
KRC refuses comes back with ok = 0. KUKAVARPROXY has no credentials of its own.

Where the robot stands (KUKA System Software 8, *System Variables*): ``$POS_ACT`` (E6POS,
the TCP of the frame ``$TOOL`` on the flange, in the frame ``$BASE``), ``$AXIS_ACT``
(E6AXIS, deg), ``$ACT_TOOL`` (the tool number selected; -1 when ``$TOOL`` was set without
one) and ``$IPO_MODE``: ``#BASE`` (the tool moves with the flange) or ``#TCP`` (external
TCP: the workpiece rides on the flange past a fixed tool, and ``$POS_ACT`` is not a tool on
the flange, so a read in that mode is refused). ``$BASE`` is in ``$WORLD``, and the robot
stands in ``$WORLD`` at ``$ROBROOT`` (KUKA, *Machine Data* KR C2 12.0400 en, 2.1.8
``$ROBROOT``: "Offset and orientation of the robot relative to the world coordinate system";
its Fig. 2 frame chain $WORLD -> $ROBROOT -> robot -> $TOOL and $WORLD -> $BASE ->
$POS_ACT), whose current value on a track is ``$ROBROOT_C`` (2.1.9 ``$ERSYSROOT``: with a
ROBROOT kinematic "the contents of the machine datum $ROBROOT are ignored. The current value
can be read from the main run variable $ROBROOT_C"). The seven are asked for in one send
(the proxy answers the requests of one TCP read in turn), so they describe one moment as
nearly as the KRC allows; the flange, in the robot's base frame, is
``inverse($ROBROOT_C) * $BASE * $POS_ACT * inverse($TOOL)`` (the flange in $WORLD when the
robot is its world, a tilted, raised or track-borne robot's in its own frame).

Variables (KUKA System Software 8, Programming manual for system integrators, "$TOOL_DATA",
"$LOAD_DATA"; declared in ``$config.dat``/``$machine.dat`` for tools 1-16):
``$TOOL_DATA[n]`` is a FRAME ``{X, Y, Z (mm), A, B, C (deg)}`` with R = Rz(A) Ry(B) Rx(C);
``$LOAD_DATA[n]`` is a LOAD ``{M (kg), CM FRAME (centre of mass, mm), J INERTIA (kg m2)}``,
M = -1 meaning "the default load" (no load data). A write sends only the members tcpcal
owns; the load's CM orientation and inertia are written back as the controller held them.

Frames (contract v1.4 "Frames at the controller"; KUKA System Software 8, *Programming
manual for system integrators*, "Measuring a base" and "Fixed tool", whose data the KRC
keeps in ``$config.dat``: ``DECL FRAME BASE_DATA[32]``, ``DECL CHAR BASE_NAME[32,24]``,
``DECL BASIS_TYPE BASE_TYPE[32]``): ``BASE_DATA[n]`` is a FRAME ``{X, Y, Z, A, B, C}`` in
``$WORLD``; ``BASE_TYPE[n]`` is ``#BASE`` for a base a tool on the flange moves through and
``#TCP`` for a fixed tool (the frame is the stationary TCP, used with ``$IPO_MODE #TCP``);
``BASE_NAME[n,]`` its name (CHAR[24], as TOOL_NAME). tcpcal holds a frame in the robot's
base frame, which stands in ``$WORLD`` at ``$ROBROOT_C`` (as for the pose read above), so
BASE_DATA[n] = $ROBROOT_C * frame, ``$ROBROOT_C`` read in the same session before the write
and with every read. The live frame is ``$ACT_BASE`` (the base number selected; -1 when a
program set ``$BASE`` itself) and ``$BASE`` (in ``$WORLD``), read in the pose read's one
send.
"""

from __future__ import annotations

import functools
import math
import socket
import struct
from collections.abc import Sequence

import numpy as np

from app.kinematics.frames import Wxyz, compose, inverse
from app.kinematics.poses import kuka_abc_from_quaternion_wxyz, quaternion_wxyz_from_kuka_abc
from app.vendors.connector import (
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
from app.vendors.kuka import FRAME_NUMBERS, KVP, TOOL_NUMBERS
from app.vendors.kuka.file import tool_name
from app.vendors.kuka.text import KrlStruct, KrlSyntaxError, format_struct, numbers, parse_struct
from app.vendors.sockets import close_quietly, open_connection, recv_exactly, send_all
from app.vendors.tool import ToolData, ToolLoad, finite_tool_data

MODE_READ = 0
MODE_WRITE = 1
_HEADER = struct.Struct("!HH")
_STATUS_OK = 1
#: KUKA's "no load data" mass: the controller uses the robot's default load.
DEFAULT_LOAD_MASS = -1.0
#: What a pose read asks the KRC for, in this order (all in one send).
POSE_VARIABLES = (
    "$IPO_MODE",
    "$ACT_TOOL",
    "$TOOL",
    "$BASE",
    "$ROBROOT_C",
    "$POS_ACT",
    "$AXIS_ACT",
    "$ACT_BASE",
)
_FRAME = ("X", "Y", "Z", "A", "B", "C")
_ROBOT_AXES = ("A1", "A2", "A3", "A4", "A5", "A6")


class KukaKvpConnector(ClosingSession):
    """One KUKAVARPROXY session on a KRC: read and write ``$TOOL_DATA[n]``/``$LOAD_DATA[n]``."""

    protocol = "kuka_kvp"

    def __init__(self, settings: ControllerSettings) -> None:
        self._settings = settings
        self._peer = f"KUKAVARPROXY at {settings.host}:{settings.port}"
        self._buffer = bytearray()
        self._msg_id = 0
        #: the whole session's time budget: connect, every read and write, the read-back
        self._deadline = Deadline(settings.timeout_s)
        self._sock: socket.socket | None = open_connection(
            settings.host, settings.port, self._deadline
        )

    # --- the Connector interface -----------------------------------------------------------

    def describe(self, target: ToolTarget) -> str:
        """``$TOOL_DATA[3]``."""
        return KVP.describe(target)

    def read_tool(self, target: ToolTarget) -> ToolData:
        """The tool frame and load the KRC holds for tool `target.slot`."""
        KVP.check(target)
        deadline = self._deadline
        frame = self._read_struct(f"$TOOL_DATA[{target.slot}]", deadline)
        x, y, z, a, b, c = numbers(frame, ("X", "Y", "Z", "A", "B", "C"), what="$TOOL_DATA")
        quaternion = _quaternion(a, b, c)
        load_struct = self._read_struct(f"$LOAD_DATA[{target.slot}]", deadline)
        return ToolData(
            position_mm=(x, y, z),
            quaternion=quaternion,
            load=_load_from_struct(load_struct),
        )

    def write_tool(self, target: ToolTarget, data: ToolData) -> None:
        """Write the frame into ``$TOOL_DATA[n]`` and, when `data.load` is set, M and CM's
        position into ``$LOAD_DATA[n]``."""
        KVP.check(target)
        finite_tool_data(data)
        deadline = self._deadline
        a, b, c = (float(v) for v in kuka_abc_from_quaternion_wxyz(np.asarray(data.quaternion)))
        x, y, z = data.position_mm
        frame = format_struct({"X": x, "Y": y, "Z": z, "A": a, "B": b, "C": c})
        load_name = f"$LOAD_DATA[{target.slot}]"
        # The load is read before anything is written: a KRC that cannot show it refuses
        # the deployment before the frame changes.
        load_text = (
            _load_text(data.load, self._read_struct(load_name, deadline))
            if data.load is not None
            else None
        )
        # From here on the KRC may hold the new frame whatever fails: the frame's write
        # may have been applied, and the load's write comes after it.
        with write_sent():
            self.write_variable(f"$TOOL_DATA[{target.slot}]", frame, deadline)
            if load_text is not None:
                self.write_variable(load_name, load_text, deadline)

    def read_pose(self) -> PoseReading:
        """Where the robot stands: the flange in the robot's base frame
        (``inverse($ROBROOT_C) * $BASE * $POS_ACT * inverse($TOOL)``), A1..A6 of
        ``$AXIS_ACT``, the tool it moves by
        (``$ACT_TOOL``, ``$TOOL``) and the six values as the KRC printed them. ControllerRefused
        in external-TCP mode (``$IPO_MODE #TCP``)."""
        readings = self.read_variables(POSE_VARIABLES, self._deadline)
        ipo_mode = readings["$IPO_MODE"].upper()
        if ipo_mode == "#TCP":
            raise ControllerRefused(
                "the robot moves in external-TCP mode ($IPO_MODE #TCP): the tool stands "
                "fixed in the cell and the workpiece rides on the flange, so $POS_ACT is not "
                "a tool on the flange and no flange pose can be taken from it. Move to the "
                "touch with the tool on the flange and External TCP off (frame data "
                "IPO_FRAME #BASE), so that $IPO_MODE reads #BASE, and capture again",
                controller_message=f"$IPO_MODE {readings['$IPO_MODE']}",
            )
        if ipo_mode != "#BASE":
            raise ControllerProtocolError(
                f"{self._peer}: $IPO_MODE = {readings['$IPO_MODE']!r} is neither #BASE nor #TCP"
            )
        tool, base, tool_inverse = _standing(
            self._numbers_of(readings, "$TOOL", _FRAME),
            self._numbers_of(readings, "$BASE", _FRAME),
            self._numbers_of(readings, "$ROBROOT_C", _FRAME),
        )
        tcp = _kuka_frame(self._numbers_of(readings, "$POS_ACT", _FRAME), remembered=False)
        position, quaternion = compose(base, tcp, tool_inverse)  # flange_from_tcp's product
        return PoseReading(
            flange=Frame(position, quaternion),
            joints_deg=self._numbers_of(readings, "$AXIS_ACT", _ROBOT_AXES),
            live_tool=LiveTool(number=self._tool_number(readings["$ACT_TOOL"]), frame=Frame(*tool)),
            readings=readings,
            live_frame=LiveFrame(
                number=self._number(readings["$ACT_BASE"], "$ACT_BASE", FRAME_NUMBERS),
                name=None,
                frame=Frame(*base),
            ),
        )

    def describe_frame(self, target: FrameTarget) -> str:
        """``BASE_DATA[3]``."""
        return KVP.describe_frame(target)

    def read_frame(self, target: FrameTarget) -> Frame:
        """BASE_DATA[slot] in the robot's base frame (``inverse($ROBROOT_C) * BASE_DATA``),
        the two read in one send."""
        name = self.describe_frame(target)
        readings = self.read_variables((name, "$ROBROOT_C"), self._deadline)
        robroot = _kuka_frame(self._numbers_of(readings, "$ROBROOT_C", _FRAME))
        world = _kuka_frame(self._numbers_of(readings, name, _FRAME))
        return Frame(*compose(inverse(*robroot), world))

    def write_frame(self, target: FrameTarget, frame: Frame) -> None:
        """Write ``BASE_DATA[slot]`` ($ROBROOT_C * frame), then ``BASE_TYPE[slot]`` (#BASE,
        or #TCP for a fixed tool) and, when the target names it, ``BASE_NAME[slot,]``."""
        name = self.describe_frame(target)
        finite_frame(frame)
        deadline = self._deadline
        robroot = _kuka_frame(
            self._numbers_of(self.read_variables(("$ROBROOT_C",), deadline), "$ROBROOT_C", _FRAME)
        )
        position, quaternion = compose(robroot, (frame.position_mm, frame.quaternion))
        a, b, c = (float(v) for v in kuka_abc_from_quaternion_wxyz(np.asarray(quaternion)))
        x, y, z = position
        value = format_struct({"X": x, "Y": y, "Z": z, "A": a, "B": b, "C": c})
        kind = "#TCP" if target.kind == "fixed_tool" else "#BASE"
        # From here on the KRC may hold the new base whatever fails.
        with write_sent():
            self.write_variable(name, value, deadline)
            self.write_variable(f"BASE_TYPE[{target.slot}]", kind, deadline)
            if target.name is not None:
                label = tool_name(target.name)
                self.write_variable(f"BASE_NAME[{target.slot},]", f'"{label}"', deadline)

    def _numbers_of(
        self, readings: dict[str, str], name: str, members: tuple[str, ...]
    ) -> tuple[float, ...]:
        """The members of structure `name` as finite numbers; ControllerProtocolError
        quoting the text when the KRC printed something else."""
        text = readings[name]
        try:
            values = numbers(parse_struct(text), members, what=name)
        except KrlSyntaxError as err:
            raise ControllerProtocolError(f"{self._peer}: {name} = {text!r}: {err}") from err
        if not all(math.isfinite(v) for v in values):
            raise ControllerProtocolError(f"{self._peer}: {name} = {text!r} is not finite")
        return values

    def _tool_number(self, text: str) -> int | None:
        """$ACT_TOOL as a tool number 1-16; None when no $TOOL_DATA entry is selected (-1)."""
        return self._number(text, "$ACT_TOOL", TOOL_NUMBERS)

    def _number(self, text: str, name: str, numbers: tuple[int, int]) -> int | None:
        """$ACT_TOOL or $ACT_BASE as a number of `numbers`; None when none is selected (-1)."""
        try:
            number = int(text)
        except ValueError as err:
            raise ControllerProtocolError(
                f"{self._peer}: {name} = {text!r} is not an integer"
            ) from err
        low, high = numbers
        return number if low <= number <= high else None

    def close(self) -> None:
        """Close the TCP connection (KUKAVARPROXY keeps no session state)."""
        close_quietly(self._sock)
        self._sock = None

    # --- the OpenShowVar exchange ----------------------------------------------------------

    def read_variable(self, name: str, deadline: Deadline | None = None) -> str:
        """The KRC's text of variable `name`; ControllerRefused when it has none."""
        deadline = deadline or self._deadline
        value, ok = self._exchange(MODE_READ, name, None, deadline)
        if not ok or not value:
            raise _no_value(name, ok)
        return value

    def _read_struct(self, name: str, deadline: Deadline) -> KrlStruct:
        text = self.read_variable(name, deadline)
        try:
            return parse_struct(text)
        except KrlSyntaxError as err:
            raise ControllerProtocolError(f"{self._peer}: {name} = {text!r}: {err}") from err

    def write_variable(self, name: str, value: str, deadline: Deadline | None = None) -> None:
        """Set variable `name` to the KRL text `value`; ControllerRefused when the KRC says no."""
        deadline = deadline or self._deadline
        _echo, ok = self._exchange(MODE_WRITE, name, value, deadline)
        if not ok:
            raise ControllerRefused(
                f"the KRC refused to set {name} (KUKAVARPROXY write status 0: the KRC has no "
                "variable of that name, or it cannot hold the value)",
                controller_message=f"{name}: write status 0",
            )

    def read_variables(self, names: tuple[str, ...], deadline: Deadline) -> dict[str, str]:
        """The KRC's text of each variable, the requests sent together and answered in
        turn; ControllerRefused naming the first the KRC has no value for."""
        requests = [(MODE_READ, name, None) for name in names]
        replies = self._exchange_all(requests, deadline)
        texts: dict[str, str] = {}
        for name, (value, ok) in zip(names, replies, strict=True):
            if not ok or not value:
                raise _no_value(name, ok)
            texts[name] = value
        return texts

    def _exchange(
        self, mode: int, name: str, value: str | None, deadline: Deadline
    ) -> tuple[str, bool]:
        (reply,) = self._exchange_all([(mode, name, value)], deadline)
        return reply

    def _exchange_all(
        self, requests: Sequence[tuple[int, str, str | None]], deadline: Deadline
    ) -> list[tuple[str, bool]]:
        """Send every request at once, then collect the replies by message id."""
        sock = self._sock
        if sock is None:
            raise ControllerUnreachable(f"{self._peer}: the session is closed")
        ids = []
        payload = b""
        for mode, name, value in requests:
            self._msg_id = (self._msg_id + 1) % 0x10000
            ids.append(self._msg_id)
            payload += encode_request(self._msg_id, mode, name, value)
        send_all(sock, payload, deadline, peer=self._peer)
        replies: dict[int, tuple[str, bool]] = {}
        while len(replies) < len(ids):
            msg_id, length = _HEADER.unpack(
                recv_exactly(sock, _HEADER.size, self._buffer, deadline, peer=self._peer)
            )
            body = recv_exactly(sock, length, self._buffer, deadline, peer=self._peer)
            if msg_id in ids:
                replies[msg_id] = decode_reply_body(body, peer=self._peer)
            # else a late answer to an earlier, timed-out request on this connection: skip it.
        return [replies[msg_id] for msg_id in ids]


def _no_value(name: str, ok: bool) -> ControllerRefused:
    return ControllerRefused(
        f"KUKAVARPROXY answered {'an empty value' if ok else 'a failed read'} for {name}",
        controller_message=f"{name}: empty value, status {int(ok)}",
        remedy=_missing_remedy(name),
    )


def _kuka_frame(
    values: tuple[float, ...], *, remembered: bool = True
) -> tuple[tuple[float, float, float], Wxyz]:
    """X, Y, Z, A, B, C (KUKA's R = Rz(A) Ry(B) Rx(C)) -> position and quaternion w, x, y, z;
    `remembered` False for $POS_ACT, whose angles a moving robot never shows twice (kept,
    they would push the fleet's tools out of `_quaternion`'s memory), and for the standing
    frames, which `_standing` remembers composed."""
    x, y, z, a, b, c = values
    return (x, y, z), (_quaternion(a, b, c) if remembered else _converted(a, b, c))


#: How many distinct A, B, C `_quaternion` keeps: the $TOOL_DATA a round reads back, 4 tools
#: for each of 4000 robots (each different), about 200 bytes an entry (3 MB).
REMEMBERED_ANGLES = 16384


@functools.lru_cache(maxsize=REMEMBERED_ANGLES)
def _quaternion(a: float, b: float, c: float) -> Wxyz:
    """KUKA A, B, C (degrees) -> quaternion w, x, y, z, remembered: every reconcile round
    reads each robot's tool, $TOOL, $BASE and $ROBROOT_C, the same angles as the round
    before while no one edits them, and scipy's conversion was a fifth of the watcher's CPU
    (py-spy --gil, bench.watch_fleet, 500 robots)."""
    return _converted(a, b, c)


_Pose = tuple[tuple[float, float, float], Wxyz]


@functools.lru_cache(maxsize=REMEMBERED_ANGLES // 4)
def _standing(
    tool: tuple[float, ...], world_base: tuple[float, ...], robroot: tuple[float, ...]
) -> tuple[_Pose, _Pose, _Pose]:
    """$TOOL, $BASE in the robot's base frame (inverse($ROBROOT_C) * $BASE) and
    inverse($TOOL), from the three as the KRC printed them, remembered: a robot's tool and
    base stand while it moves, and every round reads them again (their inverse and product
    were a tenth of the watcher's samples, py-spy --gil, bench.watch_fleet). flange_from_tcp
    is compose(base, tcp, inverse(tool)): read_pose composes these in that order."""
    tool_frame = _kuka_frame(tool, remembered=False)
    robroot_frame = _kuka_frame(robroot, remembered=False)
    base = compose(inverse(*robroot_frame), _kuka_frame(world_base, remembered=False))
    return tool_frame, base, inverse(*tool_frame)


def _converted(a: float, b: float, c: float) -> Wxyz:
    w, qx, qy, qz = (float(v) for v in quaternion_wxyz_from_kuka_abc([a, b, c]))
    return w, qx, qy, qz


def _missing_remedy(name: str) -> str:
    """What to check when the KRC shows no value for `name` (KUKAVARPROXY answers an empty
    value for a name the KRC does not resolve: not declared, or an index past its array)."""
    missing = f"the KRC has no variable {name}"
    if name.upper().startswith(("BASE_DATA[", "BASE_TYPE[", "BASE_NAME[")):
        return (
            f"{missing}: check the frame's slot (a base number the KRC declares, 1-32 on "
            f"KSS 8) and that {name.split('[', 1)[0]} is declared in the KRC's $config.dat"
        )
    if name.upper().startswith(("$TOOL_DATA[", "$LOAD_DATA[")):
        return (
            f"{missing}: check the tool's slot (a tool number the KRC declares, 1-16 on "
            f"KSS 8) and that {name.split('[', 1)[0]} is declared in the KRC's $config.dat"
        )
    return f"{missing}: check the name and that the KRC declares it"


def encode_request(msg_id: int, mode: int, name: str, value: str | None) -> bytes:
    """One OpenShowVar request: read (`value` None) or write."""
    payload = bytes([mode]) + _word_string(name)
    if value is not None:
        payload += _word_string(value)
    return _HEADER.pack(msg_id, len(payload)) + payload


def decode_reply_body(body: bytes, *, peer: str) -> tuple[str, bool]:
    """A reply's body (after id and length) -> (value text, ok)."""
    if len(body) < 3 + 3:
        raise ControllerProtocolError(f"{peer}: a reply of {len(body)} bytes is too short")
    (value_len,) = struct.unpack("!H", body[1:3])
    if 3 + value_len + 3 != len(body):
        raise ControllerProtocolError(
            f"{peer}: a reply's value length {value_len} does not fit its {len(body)} bytes"
        )
    value = body[3 : 3 + value_len].decode("latin-1")
    return value.strip(), body[-1] == _STATUS_OK


def _word_string(text: str) -> bytes:
    raw = text.encode("latin-1")
    if len(raw) > 0xFFFF:
        raise ValueError(f"{len(raw)} bytes do not fit an OpenShowVar field")
    return struct.pack("!H", len(raw)) + raw


def _load_from_struct(load: KrlStruct) -> ToolLoad | None:
    mass = load.get("M")
    cm = load.get("CM")
    if not isinstance(mass, float) or mass < 0 or not isinstance(cm, dict):
        return None  # M = -1: the KRC uses its default load; tcpcal has no load to show
    x, y, z = numbers(cm, ("X", "Y", "Z"), what="$LOAD_DATA CM")
    return ToolLoad(mass_kg=mass, cog_mm=(x, y, z))


def _load_text(load: ToolLoad, held: KrlStruct) -> str:
    """The LOAD value to write: tcpcal's mass and centre of gravity, the controller's CM
    orientation and inertia (tcpcal does not know them)."""
    cm_held = held.get("CM")
    j_held = held.get("J")
    x, y, z = load.cog_or_origin
    cm: dict[str, float] = {"X": x, "Y": y, "Z": z}
    for axis in ("A", "B", "C"):
        value = cm_held.get(axis) if isinstance(cm_held, dict) else None
        cm[axis] = value if isinstance(value, float) else 0.0
    inertia: dict[str, float] = {}
    for axis in ("X", "Y", "Z"):
        value = j_held.get(axis) if isinstance(j_held, dict) else None
        inertia[axis] = value if isinstance(value, float) else 0.0
    return format_struct({"M": load.mass_kg, "CM": cm, "J": inertia})
