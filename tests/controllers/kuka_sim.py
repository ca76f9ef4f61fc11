"""A KUKA KRC behind KUKAVARPROXY, in memory: the tool table ``$TOOL_DATA[1..16]`` and
``$LOAD_DATA[1..16]`` and the base table ``BASE_DATA[1..32]`` spoken over the OpenShowVar
protocol.

Follows KUKAVARPROXY's source (ImtsSrl/KUKAVARPROXY ``src/frmMain.frm`` ``sockServer_Read``
and ``src/basMain.bas`` ``readMsg``): big-endian words ``msg_id, length, mode, len, name
[, len, value]``; the reply ``msg_id, length, mode, len, value, 0x00 0x01, ok``; several
requests in one TCP read are answered in turn; ``PING`` answers ``PONG`` without the KRC.
What the KRC does, as KUKAVARPROXY reports it: a read it cannot resolve (unknown variable,
index outside 1-16) is an empty value with ok = 1 (``ShowVar`` returns True with an empty
value); a write it refuses answers ok = 0 with the value echoed.

How the KRC prints a structure, from ImtsSrl/openshowvar ``src/kukavar.cpp`` (its class
comment quotes a reply, ``{E6POS: X -39.86226, Y 1601.820, Z 39.84885, A -104.2217, ...}``,
and ``KukaVar::setValue`` splits members at ``", "`` and a nested structure at ``"}, "``;
an unset structure is ``{E6POS: }``) and from replies captured through KUKAVARPROXY on a
KSS 8 controller (``{E6POS: X 284.994965, Y -694.394653, Z 41.2478294, A 131.430344,
B -0.0191543195, ...}``): braces, the type name and a colon, ``NAME value`` members
separated by a comma and a space, nested structures printed the same way, a REAL with
nine significant digits (what a 32-bit float needs to read back the same), zero as ``0.0``.
This module prints and parses that text itself: it imports nothing from app/, so a
mistake the connector's writer shares with the connector's parser cannot pass here.

A write is a KRL aggregate (KUKA System Software 8, *Programming manual for system
integrators*, "Aggregates" and "Data types: STRUC"): ``{[TYPE:] NAME value, ...}``, any
spaces between tokens, a member a nested aggregate or a constant; a REAL constant is a
decimal number with an optional exponent (``-1.5E+10``), nothing Python's ``float``
accepts beyond that (no ``nan``, ``inf``, ``1_000``). The members it names change, the
others keep their values; a member the variable does not have, a value of the wrong type or
a member named twice is refused (ok = 0). The frame convention the KRC holds A, B, C in
(R = Rz(A) Ry(B) Rx(C), intrinsic Z-Y'-X'') is the reader's business: this controller
keeps the six numbers it was given.

Values are held as the KRC holds them: REAL is a 32-bit float. `set_tool` / `set_load` are
the operator at the pendant.

Where the robot stands (KUKA System Software 8, *System Variables* manual, and the
*Programming manual for system integrators*, "Coordinate systems", "Status and Turn"):
``$POS_ACT`` (E6POS) is the Cartesian position of the TCP, the frame ``$TOOL`` on the
flange, in the frame ``$BASE``; ``$BASE`` is in ``$WORLD``, and so is the robot: its root
(the robot's base frame, the flange's reference) stands at ``$ROBROOT`` in ``$WORLD``
(KUKA, *Machine Data* KR C2 12.0400 en, 2.1.8 ``$ROBROOT``: "Offset and orientation of the
robot relative to the world coordinate system", ceiling-mounted C = 180, wall-mounted
B = 90; its Fig. 2 frame chain: $WORLD -> $ROBROOT -> robot -> $TOOL, $WORLD -> $BASE ->
$POS_ACT; "The BASE coordinate system ... has the WORLD coordinate system as its reference
coordinate system"). On a track (a ROBROOT kinematic, 2.1.9 ``$ERSYSROOT``) the machine
datum ``$ROBROOT`` is ignored and "the current value can be read from the main run variable
``$ROBROOT_C``": this KRC serves both, ``$ROBROOT_C`` the current one (`set_robroot`, the
track moving the robot or the mount as built). So $POS_ACT = inverse($BASE) * $ROBROOT_C *
flange * $TOOL, the flange in the robot's base frame, A B C with
R = Rz(A) Ry(B) Rx(C); S (Status) and T (Turn: bit n set when axis n+1 stands below
0 deg) follow. ``$AXIS_ACT`` (E6AXIS) holds the axis angles A1..A6 and E1..E6.
``$ACT_TOOL`` is the number of the tool selected (-1: ``$TOOL`` was set without one), and
``$TOOL`` is ``$TOOL_DATA[$ACT_TOOL]`` (a KRC copies it at selection; this controller
reselects it after every change). ``$IPO_MODE`` is ``#BASE`` (the tool on the flange moves
through the base) or ``#TCP`` (external TCP: the workpiece rides on the flange past a fixed
tool, and ``$POS_ACT`` means something else). They print as the replies captured through
KUKAVARPROXY show them (a MATLAB session's capture, and a KRC 4 client's header quoting
``$POS_ACT`` ``{E6POS: X 1339.90503, Y 15.9216757, Z 1787.32227, A 0.0, B 89.9999466,
C -0.680795908, S 6, T 19, E1 0.0, ...}`` and ``$AXIS_ACT`` ``{E6AXIS: A1 0.0, A2 -90.0,
...}``): the REALs as above, S and T as INTs, an ENUM as ``#BASE``, an INT as ``1``.
This module computes the TCP from its own flange pose with numpy and scipy: the test sets
the flange (`set_flange`, the operator jogging) and reads it back (`flange`) to judge a
reader of ``$POS_ACT``.

The base table, as $config.dat declares it (``DECL FRAME BASE_DATA[32]``, ``DECL CHAR
BASE_NAME[32,24]``, ``BASE_TYPE[32]``; no ``$``, the names issue 48 writes):
``BASE_DATA[n]`` a FRAME (the base in ``$WORLD``), read and written as ``$TOOL_DATA[n]``
(the members named change, a member it has not refused); ``BASE_NAME[n,]`` the name, a
string of at most 24 characters printed and written as a KRL string literal ``"..."``;
``BASE_TYPE[n]`` ``#BASE`` (a base the robot moves a tool through), ``#TCP`` (a fixed tool:
the frame is the external TCP) or ``#NONE`` (unused; each base starts so); any other value
refused. A number outside 1-32 reads empty and a write is refused (ok = 0), as for tools.
``$ACT_BASE`` is the number of the base selected (-1: ``$BASE`` set without one, as a
program's own frame), and ``$BASE`` is ``BASE_DATA[$ACT_BASE]`` (a KRC copies it at
selection; this controller reselects it after every change, as for tools). The frame table
(`bases`, number -> FRAME members) is apart from the tool table: a base write changes that
one base and nothing else. The fault hook names a base write ``write BASE_DATA[n]``.
"""

from __future__ import annotations

import re
import socket
import struct
import threading
import time

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from tests.controllers.simbase import TcpSimulator

SLOTS = range(1, 17)
FRAME_MEMBERS = ("X", "Y", "Z", "A", "B", "C")
AXES = ("A1", "A2", "A3", "A4", "A5", "A6", "E1", "E2", "E3", "E4", "E5", "E6")
BASES = range(1, 33)
BASE_TYPES = ("#BASE", "#TCP", "#NONE")
NAME_LENGTH = 24
_VARIABLE = re.compile(r"^\$(TOOL_DATA|LOAD_DATA)\[\s*(-?\d+)\s*\]$", re.IGNORECASE)
_BASE_VARIABLE = re.compile(
    r"^(BASE_DATA|BASE_TYPE)\[\s*(-?\d+)\s*\]$|^(BASE_NAME)\[\s*(-?\d+)\s*,\s*\]$",
    re.IGNORECASE,
)
_KRL_STRING = re.compile(r'^\s*"([^"]*)"\s*$')


def real(value: float, single_precision: bool = True) -> float:
    """The value a KRL REAL (a 32-bit float) holds for `value`."""
    return float(np.float32(value)) if single_precision else float(value)


def print_real(value: float) -> str:
    """A REAL as the KRC prints it: nine significant digits (``284.994965``, ``-0.0191543195``),
    a whole number with ``.0``; a value no 32-bit float holds (a simulator keeping every
    written digit) with as many digits as it takes to read back the same."""
    text = f"{value:.9g}" if float(np.float32(value)) == value else repr(float(value))
    text = text.upper()
    if "." not in text and "E" not in text:
        text += ".0"
    return text


class KukaSimulator(TcpSimulator):
    """KUKAVARPROXY on a KRC with 16 tools; thread-safe pendant access."""

    name = "KUKAVARPROXY"

    def __init__(
        self, robot_name: str = "KR16_R1610_SIM", *, single_precision: bool = True
    ) -> None:
        super().__init__()
        self.robot_name = robot_name
        #: True as on a KRC (REAL is 32-bit); False keeps every written digit (to test the
        #: connector's conversions to 1e-6 without the controller's rounding)
        self.single_precision = single_precision
        self._data_lock = threading.Lock()
        self.tools: dict[int, dict[str, float]] = {
            s: dict.fromkeys(FRAME_MEMBERS, 0.0) for s in SLOTS
        }
        self.loads: dict[int, dict[str, float]] = {s: _default_load() for s in SLOTS}
        #: True: each reply goes out a few bytes at a time (as TCP may deliver it)
        self.split_replies = False
        #: every (mode, variable name, value) received, for tests that look at the wire
        self.requests: list[tuple[int, str, str | None]] = []
        # Where the robot stands: the flange in the robot's base frame (a 4x4 matrix, mm),
        # the axis angles, the selected tool and base, the interpolation mode.
        self._flange: NDArray[np.float64] = np.eye(4)
        self._flange[:3, 3] = (1000.0, 0.0, 1000.0)
        self.axes: dict[str, float] = dict.fromkeys(AXES, 0.0) | {"A2": -90.0, "A3": 90.0}
        self.act_tool = -1
        self._tool_frame: dict[str, float] = dict.fromkeys(FRAME_MEMBERS, 0.0)
        self.base: dict[str, float] = dict.fromkeys(FRAME_MEMBERS, 0.0)
        #: BASE_DATA[1..32], BASE_NAME[n,], BASE_TYPE[n] (the frame table)
        self.bases: dict[int, dict[str, float]] = {
            n: dict.fromkeys(FRAME_MEMBERS, 0.0) for n in BASES
        }
        self.base_names: dict[int, str] = dict.fromkeys(BASES, "")
        self.base_types: dict[int, str] = dict.fromkeys(BASES, "#NONE")
        #: $ACT_BASE: the base selected (-1: $BASE is `base`, a frame of the program's own)
        self.act_base = -1
        #: $ROBROOT_C: the robot's base frame in $WORLD (identity: the robot is the world)
        self.robroot: dict[str, float] = dict.fromkeys(FRAME_MEMBERS, 0.0)
        #: ``#BASE`` or ``#TCP`` (external TCP)
        self.ipo_mode = "#BASE"
        #: the Status bits S of $POS_ACT (the arm's configuration; not computed here)
        self.status = 2
        #: a moving robot: each read of $POS_ACT or $AXIS_ACT finds the flange this many mm
        #: further along the base's x axis and A1 this many degrees further
        self.moving_per_read = 0.0
        #: variables this KRC does not declare (upper case, e.g. "$LOAD_DATA[3]"): read as an
        #: empty value, a write refused, as for any name the KRC does not resolve
        self.undeclared: set[str] = set()

    # --- the pendant --------------------------------------------------------------------

    def set_tool(
        self, slot: int, x: float, y: float, z: float, a: float, b: float, c: float
    ) -> None:
        """What an operator types into the tool data on the pendant (mm, deg)."""
        with self._data_lock:
            self.tools[slot] = {
                k: real(v, self.single_precision)
                for k, v in zip(FRAME_MEMBERS, (x, y, z, a, b, c), strict=True)
            }

    def tool(self, slot: int) -> tuple[float, ...]:
        """X, Y, Z, A, B, C of $TOOL_DATA[slot] as the KRC holds them."""
        with self._data_lock:
            return tuple(self.tools[slot][k] for k in FRAME_MEMBERS)

    def set_load(self, slot: int, mass_kg: float, cog_mm: tuple[float, float, float]) -> None:
        """The operator sets $LOAD_DATA[slot]'s M and CM position."""
        with self._data_lock:
            load = self.loads[slot]
            load["M"] = real(mass_kg, self.single_precision)
            load["CM.X"], load["CM.Y"], load["CM.Z"] = (
                real(v, self.single_precision) for v in cog_mm
            )

    def load(self, slot: int) -> dict[str, float]:
        """$LOAD_DATA[slot] flattened: M, CM.X .. CM.C, J.X .. J.Z."""
        with self._data_lock:
            return dict(self.loads[slot])

    def set_flange(self, position_mm: tuple[float, ...], rotation: NDArray[np.float64]) -> None:
        """The robot jogged: its flange at `position_mm` with the 3x3 `rotation`, both in the
        robot's base frame."""
        matrix = np.eye(4)
        matrix[:3, :3] = Rotation.from_matrix(rotation).as_matrix()
        matrix[:3, 3] = position_mm
        with self._data_lock:
            self._flange = matrix

    def jog_flange(self, x: float, y: float, z: float, a: float, b: float, c: float) -> None:
        """The flange at X, Y, Z (mm) and A, B, C (deg, KUKA's convention) in the robot's base."""
        self.set_flange((x, y, z), _rotation_abc((a, b, c)).as_matrix())

    def flange(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The flange's position (mm) and 3x3 rotation in the robot's base frame."""
        with self._data_lock:
            return self._flange[:3, 3].copy(), self._flange[:3, :3].copy()

    def set_joints(self, *angles: float) -> None:
        """$AXIS_ACT's A1, A2, ... (deg; E1..E6 after A6 for external axes)."""
        with self._data_lock:
            self.axes.update(zip(AXES, (float(v) for v in angles), strict=False))

    def select_tool(self, number: int) -> None:
        """The operator selects tool `number`: $ACT_TOOL = n, $TOOL = $TOOL_DATA[n]."""
        if number not in SLOTS:
            raise ValueError(f"tool {number} is not one of 1-16")
        with self._data_lock:
            self.act_tool = number

    def set_tool_frame(self, x: float, y: float, z: float, a: float, b: float, c: float) -> None:
        """A program sets $TOOL to a frame of its own: $ACT_TOOL = -1."""
        with self._data_lock:
            self.act_tool = -1
            self._tool_frame = {
                k: real(v, self.single_precision)
                for k, v in zip(FRAME_MEMBERS, (x, y, z, a, b, c), strict=True)
            }

    def set_robroot(self, x: float, y: float, z: float, a: float, b: float, c: float) -> None:
        """$ROBROOT (and the current $ROBROOT_C): the robot's base frame in $WORLD (mm, deg),
        a robot on a track, a raised or tilted mount; the flange stays where it is on the
        robot (`set_flange` is in the robot's base frame), so $POS_ACT changes."""
        with self._data_lock:
            self.robroot = {
                k: real(v, self.single_precision)
                for k, v in zip(FRAME_MEMBERS, (x, y, z, a, b, c), strict=True)
            }

    def set_base_data(
        self, number: int, x: float, y: float, z: float, a: float, b: float, c: float
    ) -> None:
        """What an operator enters for BASE_DATA[number] on the pendant (mm, deg)."""
        with self._data_lock:
            self.bases[number] = {
                k: real(v, self.single_precision)
                for k, v in zip(FRAME_MEMBERS, (x, y, z, a, b, c), strict=True)
            }

    def base_data(self, number: int) -> tuple[float, ...]:
        """X, Y, Z, A, B, C of BASE_DATA[number] as the KRC holds them."""
        with self._data_lock:
            return tuple(self.bases[number][k] for k in FRAME_MEMBERS)

    def select_base(self, number: int) -> None:
        """The operator selects base `number`: $ACT_BASE = n, $BASE = BASE_DATA[n]."""
        if number not in BASES:
            raise ValueError(f"base {number} is not one of 1-32")
        with self._data_lock:
            self.act_base = number

    def _base_frame(self) -> dict[str, float]:
        return self.bases[self.act_base] if self.act_base in BASES else self.base

    def set_base(self, x: float, y: float, z: float, a: float, b: float, c: float) -> None:
        """$BASE: the base frame in $WORLD (mm, deg; the robot's base frame while $ROBROOT
        is the identity), set by a program: $ACT_BASE = -1."""
        with self._data_lock:
            self.act_base = -1
            self.base = {
                k: real(v, self.single_precision)
                for k, v in zip(FRAME_MEMBERS, (x, y, z, a, b, c), strict=True)
            }

    def pos_act(self) -> dict[str, float]:
        """$POS_ACT's X, Y, Z, A, B, C: the TCP of $TOOL in $BASE, from the flange."""
        with self._data_lock:
            return self._pos_act()

    def _pos_act(self) -> dict[str, float]:
        tool = self.tools[self.act_tool] if self.act_tool in SLOTS else self._tool_frame
        world_flange = _matrix(self.robroot) @ self._flange
        tcp = np.linalg.inv(_matrix(self._base_frame())) @ world_flange @ _matrix(tool)
        abc = Rotation.from_matrix(tcp[:3, :3]).as_euler("ZYX", degrees=True)
        values = (*tcp[:3, 3], *abc)
        return {
            k: real(float(v), self.single_precision)
            for k, v in zip(FRAME_MEMBERS, values, strict=True)
        }

    def _move(self) -> None:
        if self.moving_per_read:
            self._flange[0, 3] += self.moving_per_read
            self.axes["A1"] += self.moving_per_read

    def _turn(self) -> int:
        """T: bit n set when axis n+1 stands below 0 deg."""
        return sum(1 << n for n, axis in enumerate(AXES[:6]) if self.axes[axis] < 0)

    # --- the variables ------------------------------------------------------------------

    def show_var(self, name: str) -> str | None:
        """The KRC's text of a variable, None when it has none."""
        if name.strip().upper() in self.undeclared:
            return None
        if name.strip().upper() == "$ROBNAME[]":
            return f'"{self.robot_name}"'
        pose_text = self._show_pose_variable(name.strip().upper())
        if pose_text is not None:
            return pose_text
        base = _base_variable(name)
        if base is not None:
            kind, number = base
            with self._data_lock:
                if kind == "BASE_DATA":
                    return _print_frame(self.bases[number], "FRAME")
                if kind == "BASE_NAME":
                    return f'"{self.base_names[number]}"'
                return self.base_types[number]
        match = _VARIABLE.match(name.strip())
        if match is None or int(match.group(2)) not in SLOTS:
            return None
        slot = int(match.group(2))
        with self._data_lock:
            if match.group(1).upper() == "TOOL_DATA":
                return _print_frame(self.tools[slot], "FRAME")
            load = self.loads[slot]
        cm = {k: load[f"CM.{k}"] for k in FRAME_MEMBERS}
        inertia = {k: load[f"J.{k}"] for k in ("X", "Y", "Z")}
        return (
            f"{{LOAD: M {print_real(load['M'])}, CM {_print_frame(cm, 'FRAME')}, "
            f"J {_print_frame(inertia, 'INERTIA')}}}"
        )

    def _show_pose_variable(self, name: str) -> str | None:
        with self._data_lock:
            if name in ("$POS_ACT", "$AXIS_ACT"):
                self._move()
            if name == "$POS_ACT":
                pos = {k: print_real(v) for k, v in self._pos_act().items()}
                axes = ", ".join(f"{k} {print_real(self.axes[k])}" for k in AXES[6:])
                members = ", ".join(f"{k} {v}" for k, v in pos.items())
                return f"{{E6POS: {members}, S {self.status}, T {self._turn()}, {axes}}}"
            if name == "$AXIS_ACT":
                axes_real = {k: real(v, self.single_precision) for k, v in self.axes.items()}
                return _print_frame(axes_real, "E6AXIS")
            if name == "$TOOL":
                tool = self.tools[self.act_tool] if self.act_tool in SLOTS else self._tool_frame
                return _print_frame(tool, "FRAME")
            if name == "$BASE":
                return _print_frame(self._base_frame(), "FRAME")
            if name == "$ACT_BASE":
                return str(self.act_base)
            if name in ("$ROBROOT", "$ROBROOT_C"):
                return _print_frame(self.robroot, "FRAME")
            if name == "$ACT_TOOL":
                return str(self.act_tool)
            if name == "$IPO_MODE":
                return self.ipo_mode
        return None

    def set_var(self, name: str, value: str) -> bool:
        """Assign a KRL aggregate; False for what the KRC would refuse."""
        if name.strip().upper() in self.undeclared:
            return False
        if _BASE_VARIABLE.match(name.strip()):
            return self._set_base_variable(name, value)
        match = _VARIABLE.match(name.strip())
        if match is None or int(match.group(2)) not in SLOTS:
            return False
        try:
            flat = _flatten(read_aggregate(value))
        except KrlAggregateError:
            return False
        slot = int(match.group(2))
        with self._data_lock:
            target = self.tools[slot] if match.group(1).upper() == "TOOL_DATA" else self.loads[slot]
            if not set(flat) <= set(target):
                return False
            target.update({k: real(v, self.single_precision) for k, v in flat.items()})
        return True

    def _set_base_variable(self, name: str, value: str) -> bool:
        """BASE_DATA[n] (an aggregate), BASE_NAME[n,] (a string), BASE_TYPE[n] (an ENUM)."""
        base = _base_variable(name)
        if base is None:
            return False
        kind, number = base
        if kind == "BASE_NAME":
            text = _KRL_STRING.match(value)
            if text is None or len(text.group(1)) > NAME_LENGTH:
                return False
            with self._data_lock:
                self.base_names[number] = text.group(1)
            return True
        if kind == "BASE_TYPE":
            if value.strip().upper() not in BASE_TYPES:
                return False
            with self._data_lock:
                self.base_types[number] = value.strip().upper()
            return True
        try:
            flat = _flatten(read_aggregate(value))
        except KrlAggregateError:
            return False
        with self._data_lock:
            target = self.bases[number]
            if not set(flat) <= set(target):
                return False
            target.update({k: real(v, self.single_precision) for k, v in flat.items()})
        return True

    # --- the wire -----------------------------------------------------------------------

    def serve(self, conn: socket.socket) -> None:
        buffer = b""
        while True:
            chunk = conn.recv(65536)
            if not chunk:
                return
            buffer += chunk
            while len(buffer) >= 4:
                msg_id, length = struct.unpack("!HH", buffer[:4])
                if len(buffer) < 4 + length:
                    break
                body, buffer = buffer[4 : 4 + length], buffer[4 + length :]
                answer = self._answer(msg_id, body)
                if self.stalled:  # stalled mid-session: reads on, answers nothing
                    continue
                self.slow()
                if not self.split_replies:
                    conn.sendall(answer)
                    continue
                for start in range(0, len(answer), 3):
                    conn.sendall(answer[start : start + 3])
                    time.sleep(0.001)

    def _answer(self, msg_id: int, body: bytes) -> bytes:
        mode = body[0]
        fields = _split_fields(body[1:])
        name = fields[0].decode("latin-1") if fields else ""
        value = fields[1].decode("latin-1") if len(fields) > 1 else None
        self.requests.append((mode, name, value))
        stop = self.fault_at(f"{'write' if mode == 1 else 'read'} {name}")
        if stop == "before":
            return b""  # stalled: `serve` sends nothing
        if mode == 0:
            if name == "PING":
                text, ok = "PONG", True
            else:
                shown = self.show_var(name)
                text, ok = shown or "", True  # KUKAVARPROXY: ShowVar is True, value empty
        elif mode == 1 and value is not None:
            text, ok = value, self.set_var(name, value)
        else:
            text, ok = "", False
        if stop == "after":
            self.stalled = True
        raw = text.encode("latin-1")
        reply = bytes([mode]) + struct.pack("!H", len(raw)) + raw + b"\x00\x01" + bytes([int(ok)])
        return struct.pack("!HH", msg_id, len(reply)) + reply


def _base_variable(name: str) -> tuple[str, int] | None:
    """("BASE_DATA" | "BASE_NAME" | "BASE_TYPE", n) for a base variable of 1-32, else None."""
    match = _BASE_VARIABLE.match(name.strip())
    if match is None:
        return None
    kind = (match.group(1) or match.group(3)).upper()
    number = int(match.group(2) or match.group(4))
    return (kind, number) if number in BASES else None


def _split_fields(payload: bytes) -> list[bytes]:
    fields = []
    pos = 0
    while pos + 2 <= len(payload):
        (size,) = struct.unpack("!H", payload[pos : pos + 2])
        fields.append(payload[pos + 2 : pos + 2 + size])
        pos += 2 + size
    return fields


def _default_load() -> dict[str, float]:
    load = {"M": -1.0}
    load.update({f"CM.{k}": 0.0 for k in FRAME_MEMBERS})
    load.update({f"J.{k}": 0.0 for k in ("X", "Y", "Z")})
    return load


def _rotation_abc(abc: tuple[float, ...]) -> Rotation:
    """KUKA's A, B, C (deg): R = Rz(A) Ry(B) Rx(C), scipy's intrinsic "ZYX"."""
    return Rotation.from_euler("ZYX", abc, degrees=True)


def _matrix(frame: dict[str, float]) -> NDArray[np.float64]:
    """A FRAME {X, Y, Z, A, B, C} as a 4x4 matrix."""
    matrix = np.eye(4)
    matrix[:3, :3] = _rotation_abc(tuple(frame[k] for k in ("A", "B", "C"))).as_matrix()
    matrix[:3, 3] = [frame[k] for k in ("X", "Y", "Z")]
    return matrix


def _print_frame(values: dict[str, float], type_name: str) -> str:
    """``{FRAME: X 0.0, Y 0.0, ...}``: the type, a colon, members after a comma and a space."""
    return (
        "{" + f"{type_name}: " + ", ".join(f"{k} {print_real(v)}" for k, v in values.items()) + "}"
    )


# --- KRL aggregates as the KRC reads a write (this simulator's own reader) -------------------

KrlAggregate = dict[str, "float | KrlAggregate"]


class KrlAggregateError(ValueError):
    """Not a KRL aggregate of REALs this controller would accept."""


#: a KRL REAL or INT constant: digits, an optional decimal point, an optional exponent
_KRL_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[Ee][+-]?\d+)?")
#: the largest REAL (a 32-bit float) the KRC holds
REAL_MAX = float(np.finfo(np.float32).max)
_KRL_NAME = re.compile(r"[A-Za-z_$][A-Za-z0-9_$]*")
_KRL_TOKEN = re.compile(r"[{},:]|[^\s{},:]+")


def read_aggregate(text: str) -> KrlAggregate:
    """``{FRAME: X 1.0, Y 2.0}`` or ``{X 1.0,CM {X 0.0}}`` -> {"X": 1.0, ...} (names upper
    case, as KRL is case-blind); KrlAggregateError for anything else."""
    tokens = _tokens(text)
    aggregate, end = _aggregate(tokens, 0)
    if end != len(tokens):
        raise KrlAggregateError(f"text after the aggregate: {text!r}")
    return aggregate


def _tokens(text: str) -> list[str]:
    """Braces, commas, colons and the words between them; spaces only separate."""
    return _KRL_TOKEN.findall(text)


def _aggregate(tokens: list[str], pos: int) -> tuple[KrlAggregate, int]:
    if pos >= len(tokens) or tokens[pos] != "{":
        raise KrlAggregateError(f"an aggregate opens with {{, not {tokens[pos : pos + 1]}")
    pos += 1
    if pos + 1 < len(tokens) and tokens[pos + 1] == ":":  # the type name, e.g. FRAME:
        _name(tokens[pos])
        pos += 2
    members: KrlAggregate = {}
    while pos < len(tokens) and tokens[pos] != "}":
        if members:
            if tokens[pos] != ",":
                raise KrlAggregateError(f"members are separated by commas, not {tokens[pos]!r}")
            pos += 1
        name = _name(tokens[pos] if pos < len(tokens) else "")
        if name in members:
            raise KrlAggregateError(f"member {name} given twice")
        pos += 1
        if pos < len(tokens) and tokens[pos] == "{":
            members[name], pos = _aggregate(tokens, pos)
        elif pos < len(tokens) and _KRL_NUMBER.fullmatch(tokens[pos]):
            members[name], pos = float(tokens[pos]), pos + 1
        else:
            raise KrlAggregateError(f"member {name} has no REAL: {tokens[pos : pos + 1]}")
    if pos >= len(tokens):
        raise KrlAggregateError("an aggregate not closed by }")
    return members, pos + 1


def _name(token: str) -> str:
    if not _KRL_NAME.fullmatch(token):
        raise KrlAggregateError(f"{token!r} is not a KRL name")
    return token.upper()


def _flatten(members: KrlAggregate, prefix: str = "") -> dict[str, float]:
    """{"CM": {"X": 1.0}} -> {"CM.X": 1.0}; a REAL the KRC cannot hold is refused."""
    flat: dict[str, float] = {}
    for key, value in members.items():
        if isinstance(value, dict):
            flat.update(_flatten(value, f"{prefix}{key}."))
        elif abs(value) <= REAL_MAX:
            flat[f"{prefix}{key}"] = value
        else:
            raise KrlAggregateError(f"{prefix}{key} {value} does not fit a REAL")
    return flat
