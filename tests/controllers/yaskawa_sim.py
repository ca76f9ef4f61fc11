"""A Yaskawa YRC1000 / DX200 / FS100 controller's High Speed Ethernet Server (HSES), in memory:
robot control on one UDP port (10040 on a controller) and file control on another (10041),
holding a TOOL.CND of 64 tools (0-63) and a robot whose flange the test places.

Followed: Yaskawa's *Options Instructions for High-Speed Ethernet Server Function*, the FS100
edition (160766-1CD, HW1481031) with the DX100 (162529-1CD, HW1480958), DX200 (165304-1CD) and
YRC1000 (165838-1CD) editions of the same chapter 3, "Transmission Procedure" (section numbers
below are the DX100 edition's, read on its public pages; the FS100 and YRC1000 editions keep
the titles):

- 3.1 / 3.2 the packet: a 32-byte header, little-endian: ``"YERC"``, header size 0x20, data
  part size, reserve 0x03, processing division (1 robot control, 2 file control), ACK (0 a
  request, 1 an answer or a block's acknowledgement), request ID (the answer echoes it), block
  number, ``"99999999"``, then a request's sub-header: command (WORD), instance (WORD),
  attribute, service, padding; an answer's sub-header: the request's service + 0x80, status
  (0x00 normal; 0x1F with an added status of 1 or 2 WORDs; 0x08 command not defined, 0x09
  invalid element number, 0x28 instance not present, without one), added status size,
  padding, added status (WORD), padding. A data part holds at most 479 (0x1DF) bytes. 3.2.1
  (Robot Control / Status Reading) shows an answer: service 0x81, block number 0x8000_0000.
- 3.3 robot control: Status Information Reading 0x72 (instance 1; data 1: bit 0 step, 1 one
  cycle, 2 continuous, 3 running, 4 in-guard safe operation / speed limit, 5 teach, 6 play,
  7 command remote; data 2: bit 1 hold by the pendant, 2 external hold, 3 command hold, 4
  alarm, 5 error, 6 servo on), Axis Configuration Information Reading 0x74, Robot Position
  Data Reading 0x75 (3.3.6, page 3-31): instances 1-8 a robot's pulses, 101-108 its cartesian
  position, "the base coordinate only"; 13 32-bit integers: data type (0 pulse, 16 base
  frame), form, tool number, user coordinate number, extended form, eight axes (X Y Z in µm,
  Rx Ry Rz in 0.0001 deg, absent axes 0); services 0x01 (all) and 0x0E (one attribute, 1-13).
- 3.4 file control (its own port, division 2; command, instance and attribute 0, the service
  names the operation): delete 0x09, load 0x15 (PC -> controller), save 0x16 (controller ->
  PC), list 0x32 (a pattern such as ``*.CND``; names separated by CR LF). Each data block is
  acknowledged before the next; the last block's number has 0x8000_0000 set.
- The added status table (transcribed in masayuki-kono/moto-hses ``docs/specs/hses-protocol.md``
  and yrcom's ``hses_errors.py``): 2080 incorrect mode, 2090 file accessed by another function,
  5180 incorrect number of data, 5370 error in a condition file data record, E28B
  disconnected at a receive timeout, E2AF a file that cannot be deleted, E2B2 a file sent or
  received at remote OFF, E2B3 file not found, E444 processing another command (BUSY), E4A1
  block number error, E4A2 ACK error, E4A3 processing division error, E4A5 header size
  error, E4A6 identifier error, E4A7 sizes differ, E49E frame size over.

How the block exchange runs, as the manual's 3.4 and two clients read it (hsinkoyu/fs100
``send_file`` / ``recv_file``; yrcom 0.3.1 ``hses_file._write_transfer`` /
``_read_transfer``): a load's request (block 0) is answered by an ACK of block 0, then the PC
sends blocks 1..n (ACK byte 1), each answered by the same number, the last one flagged and
answered flagged; a save's or list's request is answered by block 1 of the data, each block
acknowledged by the PC echoing its number, the acknowledgement of the last one answered by
nothing.

Where the sources disagree, and what this module does:

- The answer's status bytes: the manual (3.2.1's example), moto-hses and hsinkoyu/fs100
  (``FS100AnsPacket``) put the status at byte 25, the added status size at 26 and the added
  status at 28-29; yrcom 0.3.1 reads the status at byte 26 and the added status at 30-31.
  This module follows the manual: yrcom then sees every refusal as "status 0x01, added
  0x0000", which is what its own notes say a live YRC1000 (YAS5.40) answered "for almost every
  rejected request" (``hses_errors.STATUS_CODES[0x01]``): the manual's layout read at yrcom's
  offsets.
- Rx Ry Rz: 0.0001 deg (the manual's 3.3.6, yrcom), not millidegrees (moto-hses' spec).
  R = Rz·Ry·Rx, fixed axes, as Yaskawa-Global/motoros2 composes them, in the position read and
  in TOOL.CND alike.
- Which transfers remote OFF refuses: E2B2 names sending and receiving; yrcom's notes from a
  live YRC1000 saw loads and deletes refused without command remote, reads served. This
  module refuses loads and deletes at remote OFF (E2B2) and serves saves and lists in any
  mode; a load in teach mode answers 2080 (incorrect mode), a load of TOOL.CND while the
  pendant edits it (`file_busy`) 2090.
- What the manual leaves open, chosen here: one file transfer at a time: a request while
  another transfer is open answers E444 (BUSY); a transfer whose client stopped (no packet of
  it for `transfer_timeout_s`) is dropped (E28B's receive timeout) and counted in
  `transfers_timed_out`. A loaded TOOL.CND must hold tools 0-63, each once (else 5180), each
  block in the format below (else 5370); nothing changes unless the whole file is accepted.

TOOL.CND, as the public controller backups show it (DX100/FS100 SinaiAranda/motoman_sda20d_sys,
DX200 lukelalondePZ/Fiberdome-GP88-Spindle-Cell, YRC1000 lukelalondePZ/Komatsu-Press-Demo),
one block per tool 0-63::

    //TOOL 3
    ///CRC 381761669                 (YRC1000 only; its algorithm is not public)
    ///NAME TORCH                    (``///NAME`` alone when the name is empty; 16 characters)
    12.500,0.000,215.250,0.0000,-30.0000,0.0000     X Y Z (mm, 3 decimals) Rx Ry Rz (deg, 4)
    -16.507,-21.039,-136.477         centre of gravity Xg Yg Zg (mm)
    4.200                            mass (kg)
    0.000,0.000,0.000                moments of inertia Ix Iy Iz
    0.000,0,1                        (not described publicly: kept as the controller had it)

This module parses and prints that format itself (it imports nothing of app): the controller
keeps each tool's numbers at the file's resolution (µm, 0.0001 deg, g) and prints them on
every save, CR LF line ends; a YRC1000 keeps each block's ``///CRC`` line as loaded (a block
loaded without one keeps the value it had).

The pendant: `set_tool`, `tool`, `select_tool` (the tool the robot moves by, reported by the
position read), `set_flange` / `jog_flange` (where the flange stands in the base frame),
`mode` ("teach" | "play"), `remote`, `file_busy`. The fault hook (`Faults`) names requests:
"status read", "position read", "axis configuration read" on the robot port; "save TOOL.CND",
"save TOOL.CND block 2", "load TOOL.CND", "load TOOL.CND block 2", "load TOOL.CND last
block", "list *.CND", "delete X.JBI" on the file port. `leave_transfer_open` plays a client
that began a transfer and went away.
"""

from __future__ import annotations

import contextlib
import fnmatch
import re
import socket
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from decimal import ROUND_HALF_EVEN, Decimal, InvalidOperation
from typing import Literal, Self

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from tests.controllers.simbase import Faults

# --- the packet (manual 3.1) ----------------------------------------------------------------

MAGIC = b"YERC"
HEADER_SIZE = 0x20
RESERVE_1 = 0x03
RESERVE_2 = b"99999999"
MAX_DATA = 479
LAST_BLOCK = 0x8000_0000
ROBOT = 1
FILE = 2
_HEADER = struct.Struct("<4sHHBBBBI8s")  # 24 bytes: the part requests and answers share
_REQUEST_SUB = struct.Struct("<HHBBH")  # command, instance, attribute, service, padding
_ANSWER_SUB = struct.Struct("<BBBBHH")  # service, status, added size, pad, added, pad

# Services
GET_ALL = 0x01
GET_SINGLE = 0x0E
FILE_DELETE = 0x09
FILE_LOAD = 0x15
FILE_SAVE = 0x16
FILE_LIST = 0x32

# Robot commands (3.3)
STATUS_READ = 0x72
AXIS_CONFIG_READ = 0x74
POSITION_READ = 0x75

# Status codes (the answer's byte 25)
OK = 0x00
COMMAND_UNDEFINED = 0x08
INVALID_ELEMENT = 0x09
ADDED = 0x1F
NO_INSTANCE = 0x28

# Added status codes
INCORRECT_MODE = 0x2080
FILE_IN_USE = 0x2090
INCORRECT_NUMBER_OF_DATA = 0x5180
CONDITION_FILE_RECORD = 0x5370
RECEIVE_TIMEOUT = 0xE28B
CANNOT_DELETE = 0xE2AF
REMOTE_OFF = 0xE2B2
FILE_NOT_FOUND = 0xE2B3
BUSY = 0xE444
FRAME_SIZE_OVER = 0xE49E
BLOCK_NUMBER_ERROR = 0xE4A1
ACK_ERROR = 0xE4A2
DIVISION_ERROR = 0xE4A3
HEADER_SIZE_ERROR = 0xE4A5
IDENTIFIER_ERROR = 0xE4A6
SIZE_MISMATCH = 0xE4A7

TOOL_FILE = "TOOL.CND"
TOOLS = range(64)
NAME_CHARS = 16
#: the ///CRC value of every block of the public YRC1000 backup (not a checksum of the block)
PUBLIC_CRC = "381761669"
#: data type of the cartesian position read: the base frame
BASE_FRAME = 16
PULSE = 0

Model = Literal["YRC1000", "DX200", "FS100"]


class Refusal(Exception):
    """An answer with a non-zero status (and an added status when `added` is set)."""

    def __init__(self, status: int, added: int | None = None) -> None:
        super().__init__(f"status 0x{status:02X}" + ("" if added is None else f" 0x{added:04X}"))
        self.status = status
        self.added = added


class CndError(Refusal):
    """A TOOL.CND this controller will not load: status 0x1F with `added`, and why."""

    def __init__(self, added: int, why: str) -> None:
        super().__init__(ADDED, added)
        self.why = why


# --- TOOL.CND ---------------------------------------------------------------------------------


def fixed(text: str, decimals: int) -> int:
    """A decimal number of a condition file as an integer count of 10**-decimals units
    (rounded half to even past them); CndError when it is not a finite number."""
    try:
        value = Decimal(text.strip())
    except InvalidOperation:
        raise CndError(CONDITION_FILE_RECORD, f"{text!r} is not a number") from None
    if not value.is_finite():
        raise CndError(CONDITION_FILE_RECORD, f"{text!r} is not a finite number")
    return int(value.scaleb(decimals).quantize(Decimal(1), rounding=ROUND_HALF_EVEN))


def printed(units: int, decimals: int) -> str:
    """An integer count of 10**-decimals units as the controller prints it: ``-16.507``."""
    whole, frac = divmod(abs(units), 10**decimals)
    sign = "-" if units < 0 else ""
    return f"{sign}{whole}.{frac:0{decimals}d}"


@dataclass(frozen=True)
class CndTool:
    """One tool's block as the controller keeps it: integers at the file's resolution."""

    number: int
    name: str = ""
    #: X Y Z in µm, Rx Ry Rz in 0.0001 deg
    pose: tuple[int, int, int, int, int, int] = (0, 0, 0, 0, 0, 0)
    #: centre of gravity Xg Yg Zg in µm
    cog: tuple[int, int, int] = (0, 0, 0)
    #: mass in g (the file's 0.001 kg)
    mass: int = 0
    #: moments of inertia Ix Iy Iz in 0.001 kg m2
    inertia: tuple[int, int, int] = (0, 0, 0)
    #: the block's last line, which no public document describes: kept as it was
    tail: str = "0.000,0,1"
    crc: str = PUBLIC_CRC

    def lines(self, model: Model) -> list[str]:
        """The block as the controller prints it."""
        head = [f"//TOOL {self.number}"]
        if model == "YRC1000":
            head.append(f"///CRC {self.crc}")
        head.append(f"///NAME {self.name}" if self.name else "///NAME")
        return [
            *head,
            ",".join(
                [printed(v, 3) for v in self.pose[:3]] + [printed(v, 4) for v in self.pose[3:]]
            ),
            ",".join(printed(v, 3) for v in self.cog),
            printed(self.mass, 3),
            ",".join(printed(v, 3) for v in self.inertia),
            self.tail,
        ]

    def frame(self) -> NDArray[np.float64]:
        """The tool frame in the flange frame, 4x4 (mm): R = Rz·Ry·Rx of Rx Ry Rz."""
        matrix = np.eye(4)
        matrix[:3, :3] = Rotation.from_euler(
            "xyz", [v / 1e4 for v in self.pose[3:]], degrees=True
        ).as_matrix()
        matrix[:3, 3] = [v / 1e3 for v in self.pose[:3]]
        return matrix


_TOOL_LINE = re.compile(r"//TOOL (\d+)")
_NAME_LINE = re.compile(r"///NAME(?: (.*))?")
_NUMBER = r"-?\d+(?:\.\d+)?"


def _numbers(line: str, count: int, decimals: int, what: str) -> list[int]:
    parts = line.split(",")
    if len(parts) != count or not all(re.fullmatch(_NUMBER, p.strip()) for p in parts):
        raise CndError(CONDITION_FILE_RECORD, f"{what}: {count} numbers expected, got {line!r}")
    return [fixed(p, decimals) for p in parts]


def _block(lines: list[str], at: int, kept: dict[int, CndTool]) -> tuple[CndTool, int]:
    """The block starting at line `at`, and the line after it."""
    match = _TOOL_LINE.fullmatch(lines[at])
    if match is None:
        raise CndError(CONDITION_FILE_RECORD, f"line {at + 1}: //TOOL n expected: {lines[at]!r}")
    number = int(match.group(1))
    if number not in TOOLS:
        raise CndError(CONDITION_FILE_RECORD, f"line {at + 1}: tool {number} is not 0-63")
    at += 1
    crc = kept[number].crc if number in kept else PUBLIC_CRC
    if at < len(lines) and lines[at].startswith("///CRC "):
        crc, at = lines[at][len("///CRC ") :].strip(), at + 1
    body = lines[at : at + 6]
    name = _NAME_LINE.fullmatch(body[0]) if body else None
    if name is None or len(body) < 6:
        raise CndError(CONDITION_FILE_RECORD, f"tool {number}: ///NAME and five lines expected")
    label = (name.group(1) or "").strip()
    if len(label) > NAME_CHARS or not label.isascii() or "," in label:
        raise CndError(CONDITION_FILE_RECORD, f"tool {number}: name {label!r} (16 ASCII, no ,)")
    _numbers(body[1], 6, 3, f"tool {number} X,Y,Z,Rx,Ry,Rz")
    parts = body[1].split(",")
    pose = [fixed(p, 3) for p in parts[:3]] + [fixed(p, 4) for p in parts[3:]]
    _numbers(body[5], 3, 3, f"tool {number} last line")
    tool = CndTool(
        number=number,
        name=label,
        pose=(pose[0], pose[1], pose[2], pose[3], pose[4], pose[5]),
        cog=_triple(_numbers(body[2], 3, 3, f"tool {number} Xg,Yg,Zg")),
        mass=_numbers(body[3], 1, 3, f"tool {number} W")[0],
        inertia=_triple(_numbers(body[4], 3, 3, f"tool {number} Ix,Iy,Iz")),
        tail=body[5].strip(),
        crc=crc,
    )
    return tool, at + 6


def _triple(values: list[int]) -> tuple[int, int, int]:
    return values[0], values[1], values[2]


def parse_tool_cnd(text: str, kept: dict[int, CndTool] | None = None) -> dict[int, CndTool]:
    """Every block of a TOOL.CND (CR LF or LF line ends), by tool number; CndError unless it
    holds tools 0-63, each once, each in the controller's format. `kept`: the blocks the
    controller holds (a loaded block without ``///CRC`` keeps its CRC)."""
    lines = text.replace("\r\n", "\n").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    tools: dict[int, CndTool] = {}
    at = 0
    while at < len(lines):
        tool, at = _block(lines, at, kept or {})
        if tool.number in tools:
            raise CndError(INCORRECT_NUMBER_OF_DATA, f"tool {tool.number} appears twice")
        tools[tool.number] = tool
    missing = sorted(set(TOOLS) - set(tools))
    if missing:
        raise CndError(INCORRECT_NUMBER_OF_DATA, f"tools {missing} are missing")
    return tools


def print_tool_cnd(tools: dict[int, CndTool], model: Model) -> bytes:
    """The whole file as the controller saves it: blocks 0-63, CR LF line ends."""
    lines = [line for number in TOOLS for line in tools[number].lines(model)]
    return ("\r\n".join(lines) + "\r\n").encode("ascii")


# --- packets -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Request:
    """A packet a client sent: its header and request sub-header."""

    division: int
    ack: int
    request_id: int
    block: int
    command: int
    instance: int
    attribute: int
    service: int
    data: bytes


def parse_request(packet: bytes, division: int) -> Request:
    """The packet as a request to the port serving `division`; Refusal naming what is wrong
    (identifier, header size, sizes, division) otherwise."""
    if len(packet) < HEADER_SIZE or packet[:4] != MAGIC:
        raise Refusal(ADDED, IDENTIFIER_ERROR)
    _, header_size, data_size, _, div, ack, request_id, block, _ = _HEADER.unpack_from(packet)
    if header_size != HEADER_SIZE:
        raise Refusal(ADDED, HEADER_SIZE_ERROR)
    if data_size != len(packet) - HEADER_SIZE:
        raise Refusal(ADDED, SIZE_MISMATCH)
    if data_size > MAX_DATA:
        raise Refusal(ADDED, FRAME_SIZE_OVER)
    if div != division:
        raise Refusal(ADDED, DIVISION_ERROR)
    command, instance, attribute, service, _ = _REQUEST_SUB.unpack_from(packet, 24)
    return Request(
        division=div,
        ack=ack,
        request_id=request_id,
        block=block,
        command=command,
        instance=instance,
        attribute=attribute,
        service=service,
        data=packet[HEADER_SIZE:],
    )


def answer(
    division: int,
    request_id: int,
    service: int,
    *,
    block: int = LAST_BLOCK,
    status: int = OK,
    added: int | None = None,
    data: bytes = b"",
) -> bytes:
    """An answer packet, laid out as the manual's 3.1 (status at byte 25, its added status
    size at 26, the added status at 28-29)."""
    header = _HEADER.pack(
        MAGIC, HEADER_SIZE, len(data), RESERVE_1, division, 1, request_id, block, RESERVE_2
    )
    sub = _ANSWER_SUB.pack(
        (service + 0x80) & 0xFF, status, 0 if added is None else 1, 0, added or 0, 0
    )
    return header + sub + data


# --- the controller ----------------------------------------------------------------------


@dataclass
class _Transfer:
    """An open file transfer: a save or list sending `blocks`, or a load receiving them."""

    kind: Literal["save", "load"]
    name: str
    service: int
    peer: tuple[str, int]
    request_id: int
    #: save: the number of the block whose ACK is awaited; load: the next block expected
    block: int
    blocks: list[bytes] = field(default_factory=list)
    received: bytearray = field(default_factory=bytearray)
    last_seen: float = field(default_factory=time.monotonic)


Answer = bytes | None


class YaskawaSimulator(Faults):
    """HSES on an in-memory controller: robot control and file control on two UDP ports."""

    name = "Yaskawa HSES"

    def __init__(
        self,
        *,
        model: Model = "YRC1000",
        robot_port: int = 0,
        file_port: int = 0,
        transfer_timeout_s: float = 3.0,
    ) -> None:
        self.host = "127.0.0.1"
        self.model: Model = model
        self.robot_port = robot_port
        self.file_port = file_port
        self.transfer_timeout_s = transfer_timeout_s
        #: True: receive everything, answer nothing (a controller gone silent)
        self.stalled = False
        self.tools: dict[int, CndTool] = {n: CndTool(number=n) for n in TOOLS}
        self.tools[0] = replace(self.tools[0], name="STANDARD TOOL")
        #: the pendant's mode key, command remote, servo power, a job running
        self.mode: Literal["teach", "play"] = "play"
        self.remote = True
        self.servo_on = True
        self.running = False
        #: the pendant (another function) has TOOL.CND open: a load answers 2090
        self.file_busy = False
        #: the tool number the robot moves by (the position read reports it)
        self.active_tool = 0
        #: the form (configuration bits) the position read reports: the test's to set
        self.form = 0
        #: joints S L U R B T in pulses (instance 1): the test's to set
        self.pulses: list[int] = [0] * 6
        self._flange: NDArray[np.float64] = np.eye(4)
        self._flange[:3, 3] = (895.0, 0.0, 814.0)
        #: a moving robot: each position read finds the flange this many mm further along x
        self.moving_per_read = 0.0
        #: files other than TOOL.CND, by name (loads of other names land here)
        self.files: dict[str, bytes] = {"UFRAME.CND": b"", "WEAV.CND": b""}
        #: every request handled, by its name in the fault hook's words, in order
        self.requests: list[str] = []
        self.loads_applied = 0
        self.transfers_timed_out = 0
        self._transfer: _Transfer | None = None
        #: the request a fault silences the controller after (see `_stopped_after`)
        self._pending_after: str | None = None
        self._lock = threading.RLock()
        self._sockets: list[socket.socket] = []
        self._threads: list[threading.Thread] = []

    # --- start / stop --------------------------------------------------------------------

    def start(self) -> Self:
        """Bind both ports on 127.0.0.1 (free ones unless given; the same after a `stop`)."""
        self.robot_port = self._serve(self.robot_port, self._robot)
        self.file_port = self._serve(self.file_port, self._file)
        return self

    def stop(self) -> None:
        """Close both ports (a controller switched off)."""
        sockets, self._sockets = self._sockets, []
        for sock in sockets:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()
        for thread in self._threads:
            thread.join(timeout=2)
        self._threads = [t for t in self._threads if t.is_alive()]

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _serve(self, port: int, handler: Callable[[bytes, tuple[str, int]], Answer]) -> int:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind((self.host, port))
        self._sockets.append(sock)
        thread = threading.Thread(target=self._loop, args=(sock, handler), daemon=True)
        thread.start()
        self._threads.append(thread)
        bound: int = sock.getsockname()[1]
        return bound

    def _loop(
        self, sock: socket.socket, handler: Callable[[bytes, tuple[str, int]], Answer]
    ) -> None:
        while True:
            try:
                packet, peer = sock.recvfrom(65535)
            except OSError:
                return
            if peer is None:  # shut down (`stop`): recvfrom returns at once with no sender
                return
            if self.stalled:
                continue
            with self._lock:
                reply = handler(packet, peer)
            if reply is not None and not self.stalled:
                self.slow()
                with contextlib.suppress(OSError):
                    sock.sendto(reply, peer)

    def _silent_at(self, request: str) -> bool:
        """Log `request`; True when a fault silences the controller before applying it."""
        self.requests.append(request)
        return self.fault_at(request) == "before"

    # --- the pendant ---------------------------------------------------------------------

    def set_tool(
        self,
        number: int,
        position_mm: tuple[float, float, float],
        rxyz_deg: tuple[float, float, float],
        *,
        name: str | None = None,
        mass_kg: float | None = None,
        cog_mm: tuple[float, float, float] | None = None,
    ) -> None:
        """What an operator enters in the tool file on the pendant (kept at its resolution)."""
        with self._lock:
            old = self.tools[number]
            pose = [fixed(repr(float(v)), 3) for v in position_mm]
            pose += [fixed(repr(float(v)), 4) for v in rxyz_deg]
            self.tools[number] = replace(
                old,
                name=old.name if name is None else name,
                pose=(pose[0], pose[1], pose[2], pose[3], pose[4], pose[5]),
                mass=old.mass if mass_kg is None else fixed(repr(float(mass_kg)), 3),
                cog=old.cog
                if cog_mm is None
                else _triple([fixed(repr(float(c)), 3) for c in cog_mm]),
            )

    def tool(self, number: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Tool `number`'s X Y Z (mm) and Rx Ry Rz (deg) as the controller holds them."""
        pose = self.tools[number].pose
        return tuple(v / 1e3 for v in pose[:3]), tuple(v / 1e4 for v in pose[3:])

    def tool_frame(self, number: int) -> NDArray[np.float64]:
        """Tool `number`'s frame in the flange frame, 4x4 (mm)."""
        return self.tools[number].frame()

    def tool_block(self, number: int) -> bytes:
        """Tool `number`'s block as a save prints it."""
        return ("\r\n".join(self.tools[number].lines(self.model)) + "\r\n").encode("ascii")

    def tool_cnd(self) -> bytes:
        """TOOL.CND as a save would give it now."""
        with self._lock:
            return print_tool_cnd(self.tools, self.model)

    def select_tool(self, number: int) -> None:
        """The tool the robot moves by (a job's TOOL or the pendant's tool selection)."""
        if number not in TOOLS:
            raise ValueError(f"tool {number} is not 0-63")
        self.active_tool = number

    @property
    def flange(self) -> NDArray[np.float64]:
        """The flange in the robot's base frame, 4x4 (mm)."""
        return self._flange.copy()

    def set_flange(self, matrix: NDArray[np.float64]) -> None:
        """Place the flange (4x4, mm, in the base frame)."""
        self._flange = np.array(matrix, dtype=float)

    def jog_flange(self, dx_mm: float) -> None:
        """Move the flange `dx_mm` along the base frame's x."""
        self._flange[0, 3] += dx_mm

    def tcp(self) -> NDArray[np.float64]:
        """The active tool's TCP in the base frame, 4x4 (mm): what the position read reports."""
        return self._flange @ self.tools[self.active_tool].frame()

    def leave_transfer_open(self, kind: Literal["save", "load"] = "save") -> None:
        """Another client began a save (or load) of TOOL.CND and went away: the file port
        stays busy (E444) until `transfer_timeout_s` passes."""
        with self._lock:
            service = FILE_SAVE if kind == "save" else FILE_LOAD
            self._transfer = _Transfer(kind, TOOL_FILE, service, ("127.0.0.1", 9), 1, 1)

    # --- robot control (UDP 10040) -------------------------------------------------------

    def _robot(self, packet: bytes, peer: tuple[str, int]) -> Answer:
        try:
            request = parse_request(packet, ROBOT)
        except Refusal as refusal:
            request_id = packet[11] if len(packet) > 11 else 0
            service = packet[29] if len(packet) > 29 else 0
            return answer(ROBOT, request_id, service, status=refusal.status, added=refusal.added)
        name = {
            STATUS_READ: "status read",
            AXIS_CONFIG_READ: "axis configuration read",
            POSITION_READ: "position read",
        }.get(request.command, f"command 0x{request.command:04X}")
        if self._silent_at(name):
            return None
        try:
            data = self._robot_data(request)
        except Refusal as refusal:
            reply = answer(
                ROBOT,
                request.request_id,
                request.service,
                status=refusal.status,
                added=refusal.added,
            )
        else:
            reply = answer(ROBOT, request.request_id, request.service, data=data)
        return None if self._stopped_after(name) else reply

    def _stopped_after(self, name: str) -> bool:
        """True when the fault asked about `name` silenced the controller after applying it
        (`fault_at` answered "after" for it: `stalled` is set here)."""
        if self._pending_after == name:
            self._pending_after = None
            self.stalled = True
            return True
        return False

    def fault_at(self, request: str) -> Literal["before", "after"] | None:
        stop = super().fault_at(request)
        if stop == "after":
            self._pending_after = request
        return stop

    def _robot_data(self, request: Request) -> bytes:
        values = self._robot_values(request)
        if request.service == GET_ALL:
            if request.attribute != 0:
                raise Refusal(INVALID_ELEMENT)
            return struct.pack(f"<{len(values)}i", *values)
        if request.service == GET_SINGLE:
            if not 1 <= request.attribute <= len(values):
                raise Refusal(INVALID_ELEMENT)
            return struct.pack("<i", values[request.attribute - 1])
        raise Refusal(COMMAND_UNDEFINED)

    def _robot_values(self, request: Request) -> list[int]:
        if request.command == STATUS_READ:
            if request.instance != 1:
                raise Refusal(NO_INSTANCE)
            return list(self._status())
        if request.command == POSITION_READ:
            return self._position(request.instance)
        if request.command == AXIS_CONFIG_READ:
            return self._axis_names(request.instance)
        raise Refusal(COMMAND_UNDEFINED)

    def _status(self) -> tuple[int, int]:
        data_1 = 0x04 if self.mode == "play" else 0  # continuous cycle
        data_1 |= 0x08 if self.running else 0
        data_1 |= 0x20 if self.mode == "teach" else 0x40
        data_1 |= 0x80 if self.remote and self.mode == "play" else 0
        data_2 = 0x40 if self.servo_on else 0
        return data_1, data_2

    def _position(self, instance: int) -> list[int]:
        if instance == 1:
            return [PULSE, 0, self.active_tool, 0, 0, *self.pulses, 0, 0]
        if instance != 101:
            raise Refusal(NO_INSTANCE)  # one robot (R1) on this controller
        if self.moving_per_read:
            self.jog_flange(self.moving_per_read)
        tcp = self.tcp()
        xyz = [round(v * 1000) for v in tcp[:3, 3]]
        angles = Rotation.from_matrix(tcp[:3, :3]).as_euler("xyz", degrees=True)
        rxyz = [round(v * 1e4) for v in angles]
        return [BASE_FRAME, self.form, self.active_tool, 0, 0, *xyz, *rxyz, 0, 0]

    @staticmethod
    def _axis_names(instance: int) -> list[int]:
        if instance == 1:
            names = ["S", "L", "U", "R", "B", "T"]
        elif instance == 101:
            names = ["X", "Y", "Z", "Rx", "Ry", "Rz"]
        else:
            raise Refusal(NO_INSTANCE)
        raw = b"".join(n.encode("ascii").ljust(4, b"\0") for n in names).ljust(32, b"\0")
        return list(struct.unpack("<8i", raw))

    # --- file control (UDP 10041) --------------------------------------------------------

    def _file(self, packet: bytes, peer: tuple[str, int]) -> Answer:
        try:
            request = parse_request(packet, FILE)
        except Refusal as refusal:
            request_id = packet[11] if len(packet) > 11 else 0
            service = packet[29] if len(packet) > 29 else 0
            return answer(FILE, request_id, service, status=refusal.status, added=refusal.added)
        if request.ack == 0:
            return self._file_request(request, peer)
        transfer = self._transfer
        if transfer is None or transfer.peer != peer or transfer.service != request.service:
            return None  # a stray acknowledgement (of a transfer dropped): nothing to answer
        transfer.last_seen = time.monotonic()
        if transfer.kind == "save":
            return self._save_ack(transfer, request)
        return self._load_block(transfer, request)

    def _refused(self, request: Request, refusal: Refusal, block: int = 0) -> bytes:
        return answer(
            FILE,
            request.request_id,
            request.service,
            block=block,
            status=refusal.status,
            added=refusal.added,
        )

    def _file_request(self, request: Request, peer: tuple[str, int]) -> Answer:
        name = request.data.decode("ascii", errors="replace").strip("\0 ")
        words = {FILE_SAVE: "save", FILE_LOAD: "load", FILE_LIST: "list", FILE_DELETE: "delete"}
        label = f"{words.get(request.service, f'service 0x{request.service:02X}')} {name}"
        if self._silent_at(label):
            return None
        try:
            self._check_free()
            reply = self._start(request, name, peer)
        except Refusal as refusal:
            reply = self._refused(request, refusal)
        return None if self._stopped_after(label) else reply

    def _check_free(self) -> None:
        """Refusal BUSY while another transfer is open; drop one left behind."""
        transfer = self._transfer
        if transfer is None:
            return
        if time.monotonic() - transfer.last_seen < self.transfer_timeout_s:
            raise Refusal(ADDED, BUSY)
        self._transfer = None
        self.transfers_timed_out += 1

    def _start(self, request: Request, name: str, peer: tuple[str, int]) -> Answer:
        if request.service == FILE_SAVE:
            return self._begin_send(request, name, self._content(name), peer)
        if request.service == FILE_LIST:
            names = sorted([TOOL_FILE, *self.files])
            listed = [n for n in names if fnmatch.fnmatch(n, name.upper() or "*.JBI")]
            text = "".join(f"{n}\r\n" for n in listed).encode("ascii")
            return self._begin_send(request, name, text, peer)
        if request.service == FILE_LOAD:
            self._check_load(name)
            self._transfer = _Transfer("load", name, FILE_LOAD, peer, request.request_id, 1)
            return answer(FILE, request.request_id, FILE_LOAD, block=0)
        if request.service == FILE_DELETE:
            self._delete(name)
            return answer(FILE, request.request_id, FILE_DELETE)
        raise Refusal(COMMAND_UNDEFINED)

    def _content(self, name: str) -> bytes:
        if name.upper() == TOOL_FILE:
            return print_tool_cnd(self.tools, self.model)
        if name.upper() in self.files:
            return self.files[name.upper()]
        raise Refusal(ADDED, FILE_NOT_FOUND)

    def _begin_send(
        self, request: Request, name: str, content: bytes, peer: tuple[str, int]
    ) -> bytes:
        blocks = [content[i : i + MAX_DATA] for i in range(0, len(content), MAX_DATA)] or [b""]
        transfer = _Transfer("save", name, request.service, peer, request.request_id, 1, blocks)
        self._transfer = transfer
        return self._send_block(transfer)

    def _send_block(self, transfer: _Transfer) -> bytes:
        number = transfer.block
        last = number == len(transfer.blocks)
        return answer(
            FILE,
            transfer.request_id,
            transfer.service,
            block=number | (LAST_BLOCK if last else 0),
            data=transfer.blocks[number - 1],
        )

    def _save_ack(self, transfer: _Transfer, request: Request) -> Answer:
        last = transfer.block == len(transfer.blocks)
        expected = transfer.block | (LAST_BLOCK if last else 0)
        if request.block != expected:
            self._transfer = None
            return self._refused(request, Refusal(ADDED, BLOCK_NUMBER_ERROR), request.block)
        if last:
            self._transfer = None  # the PC's ACK of the last block is answered by nothing
            return None
        transfer.block += 1
        label = f"save {transfer.name} block {transfer.block}"
        if self._silent_at(label):
            return None
        reply = self._send_block(transfer)
        return None if self._stopped_after(label) else reply

    def _check_load(self, name: str) -> None:
        if self.mode == "teach":
            raise Refusal(ADDED, INCORRECT_MODE)
        if not self.remote:
            raise Refusal(ADDED, REMOTE_OFF)
        if self.file_busy and name.upper() == TOOL_FILE:
            raise Refusal(ADDED, FILE_IN_USE)

    def _load_block(self, transfer: _Transfer, request: Request) -> Answer:
        number = request.block & ~LAST_BLOCK
        last = bool(request.block & LAST_BLOCK)
        if number != transfer.block:
            self._transfer = None
            return self._refused(request, Refusal(ADDED, BLOCK_NUMBER_ERROR), request.block)
        label = f"load {transfer.name} " + ("last block" if last else f"block {number}")
        if self._silent_at(label):
            self._transfer = None
            return None
        transfer.received += request.data
        transfer.block += 1
        reply = answer(FILE, request.request_id, FILE_LOAD, block=request.block)
        if last:
            self._transfer = None
            try:
                self._apply(transfer.name, bytes(transfer.received))
            except Refusal as refusal:
                reply = self._refused(request, refusal, request.block)
        return None if self._stopped_after(label) else reply

    def _apply(self, name: str, content: bytes) -> None:
        """A whole loaded file taken in, or CndError and nothing changed."""
        if name.upper() != TOOL_FILE:
            self.files[name.upper()] = content
            return
        try:
            text = content.decode("ascii")
        except UnicodeDecodeError:
            raise CndError(CONDITION_FILE_RECORD, "not ASCII") from None
        self.tools = parse_tool_cnd(text, self.tools)
        self.loads_applied += 1

    def _delete(self, name: str) -> None:
        if not self.remote or self.mode == "teach":
            raise Refusal(ADDED, REMOTE_OFF)
        if name.upper() == TOOL_FILE:
            raise Refusal(ADDED, CANNOT_DELETE)
        if self.files.pop(name.upper(), None) is None:
            raise Refusal(ADDED, FILE_NOT_FOUND)
