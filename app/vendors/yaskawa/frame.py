"""Yaskawa: a user frame as ``UFRAME[n]: X .. Y .. Z .. Rx .. Ry .. Rz ..`` (the text, our
layout, as the tool's ``TOOL[n]:`` line), its blocks of ``UFRAME.CND`` (the file), and their
reader.

Followed: Yaskawa Motoman's knowledge base, "Information in UFRAME.CND" (knowledge.motoman.com
article 4408441927319): a block per user frame, ``//UFRAME n``, ``///NAME`` (the name),
``///TOOL`` (the tool the frame was taught with), ``///GROUP`` (the robot group, left to
right R1, R2 ...: 1 referenced), then the taught points in pulses ``////RORG`` (ORG),
``////RXX`` (XX, the +X direction) and ``////RXY`` (XY, the +Y side), and ``////BUSER``, the
frame as X, Y, Z (mm), Rx, Ry, Rz (deg) from the robot's base frame, which the pendant
shows and edits (ROBOT - USER COORDINATE); Rx Ry Rz are the fixed-axis angles of
app.vendors.wpr. The article also lists ``///BASICFRM`` and ``///BASEP`` lines (the base
frame referenced, a base axis' position); a block without them is what public offline
programming posts write (a Visual Components Motoman post-processor's ``writeFrameInfo``:
``///NAME``, ``///TOOL 0``, ``///GROUP 1,0,...``, ``///PULSE``, ``////RORG C000=0,...``,
``////RXX C001=...``, ``////RXY C002=...``, ``////BUSER x,y,z,rx,ry,rz``), and this file
writes that shape, BUSER with TOOL.CND's decimals (3 for mm, 4 for deg).

Held against a YRC1000's own UFRAME.CND (tests/data/controller-files/yaskawa_UFRAME.CND): its
blocks read, and written back as its UFRAME, NAME, TOOL, GROUP, PULSE and BUSER lines byte for
byte; the controller's blocks also hold ``///BASICFRM 1,16,0`` and ``///BASEP`` (zeros) after
GROUP, which no public document explains and this file does not write. NOT VERIFIED: that a
controller loads a block without BASICFRM and BASEP, and what it does with taught points that
do not match BUSER.
tcpcal does not know the pulses a frame would be taught with, so RORG, RXX and RXY are
written as zeros and BUSER carries the frame; re-teaching the frame on the pendant replaces
both. Loading UFRAME.CND (EX. MEMORY - LOAD - USER COORDINATE DATA) replaces the
controller's user-frame file: a frame table holds only tcpcal's frames, so load it only onto
a controller whose other user frames are in it, or merge its blocks into the saved file.
"""

from __future__ import annotations

import re

from app.arrays import FloatArray
from app.vendors.files import ControllerFile, FileContext, split_fitting
from app.vendors.frame import FileFrame, FrameData, ParsedFrame, frame_number
from app.vendors.names import ascii_text
from app.vendors.text import NUMBER, ControllerExport, parse_error
from app.vendors.wpr import fields_text, named_values, parse_labelled, tcp_from_numbers, xyz_wpr
from app.vendors.yaskawa import FRAME_NUMBERS
from app.vendors.yaskawa.file import DEG_DECIMALS, MM_DECIMALS, tool_name
from app.vendors.yaskawa.text import FORMAT, LABELS

#: Robot groups a ///GROUP line lists (R1 first), as the public post writes it.
GROUPS = 32

_N = rf"\s*({NUMBER})\s*"
_BLOCK = re.compile(
    r"^//UFRAME\s+(\d+)\s*\n((?:///[^\n]*\n)*?)////BUSER\s+"
    rf"{_N},{_N},{_N},{_N},{_N},{_N}$",
    re.MULTILINE,
)
_NAME = re.compile(r"^///NAME ?(.*)$", re.MULTILINE)


def _fixed(value: float, decimals: int) -> str:
    return f"{round(float(value), decimals) + 0.0:.{decimals}f}"


def export(frame: FrameData) -> ControllerExport:
    """``UFRAME[n]: X .. Y .. Z .. Rx .. Ry .. Rz ..  // name`` (mm, deg)."""
    slot = frame_number(frame, "Yaskawa", "UFRAME.CND's //UFRAME n", FRAME_NUMBERS)
    six = xyz_wpr(frame)
    values: dict[str, object] = {"slot": slot, **named_values(LABELS, six)}
    text = f"UFRAME[{slot}]: {fields_text(LABELS, six)}  // {ascii_text(frame.name, 40)}"
    return ControllerExport(format=FORMAT, text=text, values=values)


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. Rx .. Ry .. Rz ..``, or a UFRAME.CND block's ``////BUSER`` ->
    (position (3,) mm, quaternion wxyz (4,))."""
    match = _BLOCK.search(text.replace("\r\n", "\n"))
    if match is not None:
        return tcp_from_numbers([float(g) for g in match.groups()[2:]])
    return parse_labelled(FORMAT, LABELS, text)


def block(frame: FrameData) -> list[str]:
    """One user frame's lines."""
    numbers = xyz_wpr(frame)
    buser = [_fixed(v, MM_DECIMALS) for v in numbers[:3]]
    buser += [_fixed(v, DEG_DECIMALS) for v in numbers[3:]]
    group = ",".join(["1"] + ["0"] * (GROUPS - 1))
    return [
        f"//UFRAME {frame.slot}",
        f"///NAME {tool_name(frame.name)}".rstrip(),
        "///TOOL 0",
        f"///GROUP {group}",
        "///PULSE",
        "////RORG C000=0,0,0,0,0,0",
        "////RXX C001=0,0,0,0,0,0",
        "////RXY C002=0,0,0,0,0,0",
        f"////BUSER {','.join(buser)}",
    ]


def _check(frame: FrameData) -> None:
    export(frame)


def write(frames: list[FileFrame], context: FileContext) -> ControllerFile:
    """The frames' blocks by user frame number (a condition file has no comments: no
    header)."""
    kept, left = split_fitting(frames, _check, context)
    lines: list[str] = []
    for item in sorted(kept, key=lambda f: f.data.slot or 0):
        lines += block(item.data)
    text = "\n".join(lines) + "\n" if lines else ""
    return ControllerFile(FORMAT, "UFRAME.CND", text, tuple(left))


def read(text: str) -> list[ParsedFrame]:
    """Every //UFRAME block of a UFRAME.CND text (its ///NAME and ////BUSER)."""
    frames = []
    for match in _BLOCK.finditer(text.replace("\r\n", "\n")):
        named = _NAME.search(match.group(2))
        name = named.group(1).strip() if named is not None else ""
        position, quaternion = tcp_from_numbers([float(g) for g in match.groups()[2:]])
        frames.append(ParsedFrame(int(match.group(1)), name or None, position, quaternion))
    if not frames:
        raise parse_error(FORMAT, "UFRAME.CND blocks (//UFRAME n ... ////BUSER x,y,z,...)", text)
    return frames
