"""Yaskawa tool files over the High Speed Ethernet Server (YRC1000, DX200, FS100): a tool is
its block of TOOL.CND, tool numbers 0-63 (the tool's `slot`).

Followed: Yaskawa's *Options Instructions for High-Speed Ethernet Server Function* (FS100
160766-1CD; DX100 162529-1CD, DX200 165304-1CD, YRC1000 165838-1CD), chapter 3: robot control
on UDP 10040 (Status Information Reading 0x72; Robot Position Data Reading 0x75, instance 101
= R1 in cartesian coordinates, "the base coordinate only": data type 16, form, tool number,
user coordinate number, extended form, X Y Z in µm, Rx Ry Rz in 0.0001 deg) and file control
on UDP 10041 (File Saving 0x16, File Loading 0x15, in blocks of at most 479 bytes, each
acknowledged). The packets and their codes are app.vendors.yaskawa.hses_wire's.

A deployment (`write_tool`) saves TOOL.CND from the controller, replaces the tool's numbers in
its own block (the X Y Z Rx Ry Rz line; the centre of gravity and mass lines when tcpcal has
the tool's load, else the controller's load is kept), and loads the file back: every other
byte (the other 63 blocks, the block's ``///NAME``, a YRC1000's ``///CRC``, the inertia and
last lines, the CR LF line ends) is the controller's own. The read-back (`read_tool`) saves
the file again. The values are written at the file's resolution (3 decimals of mm, 4 of deg,
3 of kg). Rx Ry Rz: R = Rz·Ry·Rx, the fixed-axis angles of app.kinematics.poses'
``fanuc_wpr`` (the same convention: app.vendors.wpr; app.vendors.yaskawa.text says where it
is confirmed). TOOL.CND is what the controller keeps: the tool stays after a restart (scope
"stored").

Where the robot stands (`read_pose`, contract v1.3): the position read 0x75 (instance 101)
gives the TCP of the tool the robot moves by in the base frame and that tool's number n; the
flange is that TCP times the inverse of tool n's frame, read from TOOL.CND in the same
session. Joints: the pulse read (instance 1) is kept in the readings; degrees would need the
controller's pulse-per-degree parameters, which HSES does not serve, so `joints_deg` is None.

Frames (contract v1.4: Yaskawa's user frames live in UFRAME.CND, "where its documents show
how a frame is written", else 501 /no-frame-writer): HSES has no user-frame command (the
manual's robot control commands read status, positions, variables, alarms and I/O; MotoCom's
BscPutUFrame has no HSES counterpart), only the file load that writes TOOL.CND here. UFRAME.CND
keeps, per user frame, the three points it was taught at (``RORG``, ``RXX``, ``RXY``: the
robot's axis positions in pulses, S L U R B T and the 7th-9th axes) beside the frame they
define (``BUSER``: X Y Z Rx Ry Rz from the basic frame), and BUSER can be edited at the pendant
apart from the points (Yaskawa Motoman knowledge base, "Information in UFRAME.CND": ROBOT -
USER COORDINATE - DISPLAY; "as with all files modified after download, proceed with caution
before uploading to the controller"). No Yaskawa document says what the controller does when
it loads a UFRAME.CND whose BUSER no longer matches the pulses of its taught points (keep
BUSER, compute the frame again from RORG/RXX/RXY, or refuse), nor which of the two a later
touch-up on the pendant starts from, so tcpcal writes no user frame and reads none:
`write_frame` and `read_frame` raise `FrameWriterMissing` naming UFRAME.CND, to be loaded
and checked by hand, nothing sent. The position read names no live frame: instance 101
answers "the base coordinate only" (data type 16), and its user coordinate number belongs to
a position in user coordinates, not to the frame a job moves in, so the live frame is unread.

Refusals: a load refused by the controller (teach mode 2080, remote OFF E2B2, the file in use
2090, ...) is ControllerRefused naming its status and added status in words, with what to do
at the controller; nothing was loaded. The load's data blocks are sent under `write_sent`:
once one has left, the controller may take the file (it applies it at the last block), so a
failure after that leaves the deployment unverified until read again.

Timeouts: UDP has no connection. Every request is under the session's one deadline
(``timeout_s`` from `connect`): a robot control read is sent again every `RESEND_S` while
unanswered; a file request waits for its answer (sent again, it would meet the transfer it
opened as busy); a save or load request the controller answers as busy (another transfer, or
one a failed client left behind, which the controller drops after its receive timeout) is
made again until the deadline; a load's blocks are sent once. A transfer this
connector abandons (its deadline spent mid-way) has no cancel command in the protocol: the
controller drops it at its own receive timeout, and the next attempt's busy answers are
asked again until then.
"""

from __future__ import annotations

import re
import struct
import time

import numpy as np

from app.kinematics.frames import flange_from_tcp
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
    FramesByHand,
    FrameTarget,
    LiveTool,
    PoseReading,
    ToolTarget,
    write_sent,
)
from app.vendors.tool import ToolData, ToolLoad, finite_tool_data
from app.vendors.yaskawa import HSES
from app.vendors.yaskawa.hses_wire import (
    BUSY,
    FILE_CONTROL,
    FILE_LOAD,
    FILE_SAVE,
    GET_ALL,
    LAST_BLOCK,
    MAX_DATA,
    ROBOT_CONTROL,
    Answer,
    HsesRefusal,
    UdpPort,
    checked,
    request_packet,
)

TOOL_FILE = "TOOL.CND"
#: The user frame file, and why tcpcal writes it not (the module's "Frames").
UFRAME_FILE = "UFRAME.CND"
NO_UFRAME_WRITER = (
    "HSES has no user-frame command, and no Yaskawa document says what the controller does "
    "with a UFRAME.CND loaded over HSES file control whose frame (BUSER) no longer matches "
    "the taught points it keeps in pulses (RORG, RXX, RXY): it may keep the frame or compute "
    "it again from the points, so tcpcal writes no user frame (check a frame loaded by hand "
    "under ROBOT - USER COORDINATE - DISPLAY on the pendant)"
)
STATUS_READ = 0x72
POSITION_READ = 0x75
#: 0x75 instances: R1's pulses, R1 in cartesian coordinates (the base frame)
R1_PULSES = 1
R1_CARTESIAN = 101
BASE_FRAME = 16
#: how often a busy file control is asked again
BUSY_RETRY_S = 0.05

#: What to do at the controller about a refusal, by added status.
REMEDIES: dict[int, str] = {
    0x2080: (
        "loading a file over HSES needs the controller in remote mode: turn the pendant's "
        "mode key to REMOTE (not TEACH) and deploy again"
    ),
    0xE2B2: (
        "remote is OFF: turn the pendant's mode key to REMOTE and check that command remote "
        "is enabled for Ethernet (yrcom's notes name parameter RS005 = 1), then deploy again"
    ),
    0x2100: "command remote is not set: enable it (RS005 = 1 per yrcom's notes) and retry",
    0x2090: (
        "another function has TOOL.CND open (the tool file screen on the pendant, a backup "
        "in progress): close it there and deploy again"
    ),
    0x2130: "the pendant is editing: finish or cancel the edit and deploy again",
    0x2010: "the robot is moving: stop the job and deploy again",
    0x6010: "the robot is in operation: stop the job and deploy again",
    0xE444: (
        "the controller's file control is busy with another transfer (another client's, or "
        "one left behind that it drops at its receive timeout): deploy again shortly"
    ),
}

_POSE_LINE = re.compile(r"^[-+0-9.eE]+(?:,[-+0-9.eE]+){5}$")
_TRIPLE_LINE = re.compile(r"^[-+0-9.eE]+(?:,[-+0-9.eE]+){2}$")
_ONE_LINE = re.compile(r"^[-+0-9.eE]+$")


def _fixed(value: float, decimals: int) -> str:
    return f"{round(float(value), decimals) + 0.0:.{decimals}f}"


def _lines_of_tool(lines: list[str], number: int) -> tuple[int, int, int]:
    """Indexes of tool `number`'s pose, centre-of-gravity and mass lines in TOOL.CND's
    `lines` (with their ends); ControllerProtocolError when the file has no such block."""
    heads = [i for i, line in enumerate(lines) if line.rstrip("\r\n") == f"//TOOL {number}"]
    if len(heads) != 1:
        raise ControllerProtocolError(
            f"the controller's {TOOL_FILE} has {len(heads)} blocks //TOOL {number}, not one"
        )
    at = heads[0] + 1
    while at < len(lines) and lines[at].startswith("///") and not lines[at].startswith("///NAME"):
        at += 1  # ///CRC (YRC1000)
    if at >= len(lines) or not lines[at].startswith("///NAME"):
        raise ControllerProtocolError(f"{TOOL_FILE} //TOOL {number} has no ///NAME line")
    pose, cog, mass = at + 1, at + 2, at + 3
    shapes = ((pose, _POSE_LINE), (cog, _TRIPLE_LINE), (mass, _ONE_LINE))
    for index, shape in shapes:
        if index >= len(lines) or not shape.match(lines[index].rstrip("\r\n")):
            raise ControllerProtocolError(
                f"{TOOL_FILE} //TOOL {number}: line {index + 1} is not what a tool file holds"
            )
    return pose, cog, mass


def replace_tool(saved: bytes, number: int, data: ToolData) -> bytes:
    """The controller's TOOL.CND `saved` with tool `number`'s X Y Z Rx Ry Rz (and, with a
    load, Xg Yg Zg and W) replaced; every other byte as it was."""
    try:
        text = saved.decode("ascii")
    except UnicodeDecodeError as err:
        raise ControllerProtocolError(f"the controller's {TOOL_FILE} is not ASCII") from err
    lines = text.splitlines(keepends=True)
    pose, cog, mass = _lines_of_tool(lines, number)
    rx, ry, rz = (float(v) for v in fanuc_wpr_from_quaternion_wxyz(np.asarray(data.quaternion)))
    values = [_fixed(v, 3) for v in data.position_mm] + [_fixed(v, 4) for v in (rx, ry, rz)]
    _set_line(lines, pose, ",".join(values))
    if data.load is not None:
        _set_line(lines, cog, ",".join(_fixed(v, 3) for v in data.load.cog_or_origin))
        _set_line(lines, mass, _fixed(data.load.mass_kg, 3))
    return "".join(lines).encode("ascii")


def _set_line(lines: list[str], index: int, content: str) -> None:
    body = lines[index].rstrip("\r\n")
    lines[index] = content + lines[index][len(body) :]


def read_tool_block(saved: bytes, number: int) -> tuple[ToolData, str]:
    """Tool `number` of the controller's TOOL.CND (its load when its mass is above 0) and
    its pose line as the controller printed it."""
    lines = saved.decode("ascii", errors="replace").splitlines(keepends=True)
    pose, cog, mass = _lines_of_tool(lines, number)
    try:
        numbers = [float(v) for v in lines[pose].strip().split(",")]
        centre = [float(v) for v in lines[cog].strip().split(",")]
        kg = float(lines[mass].strip())
    except ValueError as err:
        raise ControllerProtocolError(f"{TOOL_FILE} //TOOL {number}: {err}") from err
    if not all(np.isfinite([*numbers, *centre, kg])):
        raise ControllerProtocolError(f"{TOOL_FILE} //TOOL {number} holds a value not finite")
    frame = _frame(numbers)
    load = ToolLoad(kg, (centre[0], centre[1], centre[2])) if kg > 0 else None
    return ToolData(frame.position_mm, frame.quaternion, load), lines[pose].strip()


def _frame(values: list[float]) -> Frame:
    """X Y Z (mm) Rx Ry Rz (deg) as a Frame."""
    q = quaternion_wxyz_from_fanuc_wpr(values[3:6])
    return Frame(
        (values[0], values[1], values[2]), (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
    )


class YaskawaHsesConnector(FramesByHand, ClosingSession):
    """One session with a Yaskawa controller's High Speed Ethernet Server; user frames by
    hand (the module's "Frames")."""

    protocol = "yaskawa_hses"
    frame_reason = NO_UFRAME_WRITER
    frame_file = UFRAME_FILE

    def __init__(self, settings: ControllerSettings) -> None:
        self._deadline = Deadline(settings.timeout_s)
        host = settings.host
        robot, file = HSES.port_of(settings, "robot"), HSES.port_of(settings, "file")
        self._robot = UdpPort(host, robot, ROBOT_CONTROL, self._deadline)
        self._file = UdpPort(host, file, FILE_CONTROL, self._deadline)
        self._where = f"the Yaskawa controller at {host}"
        # The status read: is the High Speed Ethernet Server there? (UDP has no connection
        # that would fail: only an answer tells.)
        self._robot_read(STATUS_READ, 1)

    # --- the Connector interface -----------------------------------------------------------

    def describe(self, target: ToolTarget) -> str:
        """``TOOL.CND tool 3``."""
        return HSES.describe(target)

    def read_tool(self, target: ToolTarget) -> ToolData:
        """Tool `slot`'s frame (and load, when its mass is above 0) in the controller's
        TOOL.CND, saved from the controller now."""
        HSES.check(target)
        assert target.slot is not None  # HSES.check: a slot-addressed protocol
        data, _line = read_tool_block(self.save(TOOL_FILE), target.slot)
        return data

    def write_tool(self, target: ToolTarget, data: ToolData) -> None:
        """Save TOOL.CND, replace tool `slot`'s numbers, load the file back."""
        HSES.check(target)
        finite_tool_data(data)
        assert target.slot is not None
        content = replace_tool(self.save(TOOL_FILE), target.slot, data)
        self.load(TOOL_FILE, content)

    def describe_frame(self, target: FrameTarget) -> str:
        """``UFRAME.CND user frame 3``."""
        return HSES.describe_frame(target)

    def read_pose(self) -> PoseReading:
        """The flange in the base frame: the position read (the reported tool's TCP in the
        base frame) times the inverse of that tool's frame in TOOL.CND."""
        values = self._robot_read(POSITION_READ, R1_CARTESIAN)
        if len(values) < 11 or values[0] != BASE_FRAME or not 0 <= values[2] <= 63:
            raise ControllerProtocolError(
                f"{self._where}: the position read (0x75, 101) answered {values}: not a "
                "base-frame position with a tool number 0-63"
            )
        number = values[2]
        tcp = _frame([v / 1000 for v in values[5:8]] + [v / 10000 for v in values[8:11]])
        tool, line = read_tool_block(self.save(TOOL_FILE), number)
        pulses = self._robot_read(POSITION_READ, R1_PULSES)
        flange = flange_from_tcp(
            (tcp.position_mm, tcp.quaternion), tool=(tool.position_mm, tool.quaternion)
        )
        readings = {
            "0x75 R1 cartesian (base)": _position_words(values),
            "0x75 R1 pulses": " ".join(str(v) for v in pulses[5:]),
            f"{TOOL_FILE} //TOOL {number}": line,
        }
        return PoseReading(
            flange=Frame(*flange),
            joints_deg=None,
            live_tool=LiveTool(number=number, frame=Frame(tool.position_mm, tool.quaternion)),
            readings=readings,
            live_frame=UNREAD_FRAME,
        )

    def close(self) -> None:
        """Close both sockets (UDP: nothing to release on the controller); never raises."""
        self._robot.close()
        self._file.close()

    # --- robot control ---------------------------------------------------------------------

    def _robot_read(self, command: int, instance: int) -> tuple[int, ...]:
        """A robot control read (Get_Attribute_All) as its 32-bit integers."""
        _, answer = self._robot.ask(
            lambda rid: request_packet(
                ROBOT_CONTROL, rid, command=command, instance=instance, service=GET_ALL
            ),
            GET_ALL,
            resend=True,
        )
        try:
            checked(answer)
        except HsesRefusal as refusal:
            raise self._refused(
                f"the read 0x{command:02X} (instance {instance})", refusal
            ) from None
        count = len(answer.data) // 4
        return struct.unpack(f"<{count}i", answer.data[: count * 4])

    # --- file control ----------------------------------------------------------------------

    def save(self, name: str) -> bytes:
        """File Saving (0x16): the file from the controller, each block acknowledged; the
        request asked again while the controller answers busy, until the deadline."""
        request_id, answer = self._request(FILE_SAVE, name, f"the save of {name}")
        chunks = []
        expected = 1
        while True:
            self._checked(answer, f"the save of {name}")
            if answer.block & ~LAST_BLOCK != expected:
                raise ControllerProtocolError(
                    f"{self._where} sent block {answer.block & ~LAST_BLOCK} of {name}, "
                    f"block {expected} expected"
                )
            chunks.append(answer.data)
            self._file.send(
                request_packet(
                    FILE_CONTROL, request_id, service=FILE_SAVE, ack=1, block=answer.block
                )
            )
            if answer.block & LAST_BLOCK:
                return b"".join(chunks)
            expected += 1
            answer = self._next(request_id, FILE_SAVE)

    def load(self, name: str, content: bytes) -> None:
        """File Loading (0x15): the request (asked again while the controller answers busy),
        then the blocks, each answered; the blocks under `write_sent`."""
        request_id, answer = self._request(FILE_LOAD, name, f"the load of {name}")
        self._checked(answer, f"the load of {name}")
        blocks = [content[i : i + MAX_DATA] for i in range(0, len(content), MAX_DATA)] or [b""]
        with write_sent():
            for number, part in enumerate(blocks, 1):
                block = number | (LAST_BLOCK if number == len(blocks) else 0)
                self._file.send(
                    request_packet(
                        FILE_CONTROL, request_id, service=FILE_LOAD, ack=1, block=block, data=part
                    )
                )
                self._checked(self._next(request_id, FILE_LOAD), f"the load of {name}")

    def _request(self, service: int, name: str, what: str) -> tuple[int, Answer]:
        """A file control request for `name` and its first answer, the request made again
        while the controller answers busy (until the deadline)."""
        while True:
            request_id, answer = self._file.ask(
                lambda rid: request_packet(
                    FILE_CONTROL, rid, service=service, data=name.encode("ascii")
                ),
                service,
                resend=False,
            )
            if answer.status == 0 or answer.added not in BUSY:
                return request_id, answer
            if self._deadline.left() <= BUSY_RETRY_S:
                raise self._refused(what, HsesRefusal(answer.status, answer.added))
            time.sleep(BUSY_RETRY_S)

    def _next(self, request_id: int, service: int) -> Answer:
        """The next packet of a transfer, within the deadline (ControllerUnreachable)."""
        answer = self._file.receive(request_id, service, self._deadline.left())
        if answer is None:
            self._deadline.remaining()  # raises ControllerUnreachable: the deadline is spent
            raise ControllerUnreachable(f"{self._where} went silent mid-transfer")
        return answer

    def _checked(self, answer: Answer, what: str) -> Answer:
        try:
            return checked(answer)
        except HsesRefusal as refusal:
            raise self._refused(what, refusal) from None

    def _refused(self, what: str, refusal: HsesRefusal) -> ControllerRefused:
        words = str(refusal)
        remedy = REMEDIES.get(refusal.added) if refusal.added is not None else None
        return ControllerRefused(
            f"{self._where} refused {what}: {words}", controller_message=words, remedy=remedy
        )


def _position_words(values: tuple[int, ...]) -> str:
    """The position read as the pendant would show it: type, form, tool, X..Rz."""
    x, y, z = (f"{v / 1000:.3f}" for v in values[5:8])
    rx, ry, rz = (f"{v / 10000:.4f}" for v in values[8:11])
    return (
        f"type {values[0]} form {values[1]} tool {values[2]} user {values[3]} "
        f"X {x} Y {y} Z {z} Rx {rx} Ry {ry} Rz {rz}"
    )
