"""KUKA: a frame as ``BASE_DATA[n]={X ..,Y ..,Z ..,A ..,B ..,C ..}`` (the text), and the
frame's lines of ``KRC:\\R1\\System\\$config.dat`` (the file), with their reader.

Followed: KUKA System Software 8.x *Operating and Programming Instructions for System
Integrators*, "Base calibration" and "External TCP" (a base is a FRAME in the world frame, mm
and deg, R = Rz(A) Ry(B) Rx(C); an external TCP, a tool standing in the cell, is kept in the
base table and used with ``$IPO_MODE #TCP``), and the $config.dat of a KSS 8 controller in a
public robot-cell repository (EdgarMontielG/Cell-3_R10 KRC/R1/System/$config.dat, trimmed in
tests/data/controller-files/kuka_config_bases.dat), which declares the base table as::

    INT MAX_BASE=32
    DECL FRAME BASE_DATA[32]
    BASE_DATA[3]={X 21.8400,Y 1866.09,Z 658.470,A 90.0000,B 0.0,C 180.000}
    DECL CHAR BASE_NAME[32,24]
    BASE_NAME[3,]="NUT WELDER"          (" " for an unused base)
    DECL IPO_M_T BASE_TYPE[32]
    BASE_TYPE[3]=#BASE                   (#NONE unused, #TCP an external TCP)

The numbers are those of the JSON text, printed as app.vendors.text prints them (the fewest
digits that keep 1e-6 mm and deg; the controller's own six significant digits would lose up
to 0.01 mm at 1333.94). What it changes, and how the controller merges it: as the tool file
(app.vendors.kuka.file), each frame's three elements as single-element assignments, never
the whole arrays: replace the lines of the same numbers in $config.dat (every other base and
the DECL lines stay), or run them as KRL assignments.
"""

from __future__ import annotations

import re

from app.arrays import FloatArray
from app.vendors.files import ControllerFile, FileContext, header_comments, split_fitting
from app.vendors.frame import NOUN, FileFrame, FrameData, ParsedFrame, frame_number
from app.vendors.kuka import FRAME_NUMBERS
from app.vendors.kuka.file import LINE_WIDTH, tool_name
from app.vendors.kuka.text import FORMAT, KrlSyntaxError, krl_frame, pose_of_frame
from app.vendors.names import file_stem
from app.vendors.text import ControllerExport, checked_tcp, parse_error

#: BASE_TYPE of a base, and of an external TCP (a fixed tool) kept in the base table.
BASE_TYPE = "#BASE"
EXTERNAL_TCP_TYPE = "#TCP"

_ASSIGNMENT = re.compile(
    r"(?<![A-Za-z0-9_])\$?BASE_DATA\[\s*(\d+)\s*\]\s*=\s*(\{[^{}]*\})", re.IGNORECASE
)
_NAME = re.compile(
    r'^\s*\$?BASE_NAME\[\s*(\d+)\s*,\s*\]\s*=\s*"([^"]*)"', re.IGNORECASE | re.MULTILINE
)
_TYPE = re.compile(r"^\s*\$?BASE_TYPE\[\s*(\d+)\s*\]\s*=\s*(#\w+)", re.IGNORECASE | re.MULTILINE)


def base_type(frame: FrameData) -> str:
    """The frame's BASE_TYPE: #TCP for a fixed tool (an external TCP), else #BASE."""
    return EXTERNAL_TCP_TYPE if frame.fixed_tool else BASE_TYPE


def export(frame: FrameData) -> ControllerExport:
    """``BASE_DATA[n]={X,Y,Z (mm),A,B,C (deg)}``; 422 at "slot" without a frame number."""
    slot = frame_number(frame, "KUKA", "BASE_DATA[n]", FRAME_NUMBERS)
    position, quaternion = checked_tcp(frame)
    members, value = krl_frame(position, quaternion)
    values: dict[str, object] = {
        "slot": slot,
        **members,
        "name": tool_name(frame.name),
        "type": base_type(frame),
    }
    return ControllerExport(format=FORMAT, text=f"BASE_DATA[{slot}]={value}", values=values)


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """``BASE_DATA[n]={X,Y,Z,A,B,C}`` (``$`` or not) -> (position (3,) mm, quaternion wxyz)."""
    match = _ASSIGNMENT.search(text)
    try:
        if match is None:
            raise KrlSyntaxError("no BASE_DATA[n]= assignment")
        return pose_of_frame(match.group(2))
    except KrlSyntaxError as err:
        raise parse_error(FORMAT, "BASE_DATA[n]={X x,Y y,Z z,A a,B b,C c}", text) from err


def write(frames: list[FileFrame], context: FileContext) -> ControllerFile:
    """Each frame's BASE_DATA[n], BASE_NAME[n,] and BASE_TYPE[n] line, by frame number."""
    kept, left = split_fitting(frames, export, context)
    by_slot = {item.data.slot: item.data for item in sorted(kept, key=lambda f: f.data.slot or 0)}
    lines = header_comments(kept, left, context, _how(by_slot), "; ", LINE_WIDTH, NOUN)
    for slot, frame in by_slot.items():
        lines.append(export(frame).text)
        lines.append(f'BASE_NAME[{slot},]="{tool_name(frame.name)}"')
        lines.append(f"BASE_TYPE[{slot}]={base_type(frame)}")
    if context.table:
        name = "config_bases.dat"
    else:
        name = f"base{kept[0].data.slot}_{file_stem(kept[0].data.name)}.dat"
    return ControllerFile(FORMAT, name, "\n".join(lines) + "\n", tuple(left))


def _how(by_slot: dict[int | None, FrameData]) -> list[str]:
    """The header's sentences on what the file changes and how it is applied."""
    if not by_slot:
        return ["changes nothing on the controller: it holds no frame"]
    numbers = ", ".join(str(n) for n in by_slot)
    sentences = [
        f"changes only base(s) {numbers}: their BASE_DATA, BASE_NAME and BASE_TYPE elements; "
        "every other base is untouched",
        "replace the lines of the same numbers in KRC:\\R1\\System\\$config.dat with these "
        "(keep the DECL lines and every other line), or run them as KRL assignments",
    ]
    fixed = [str(n) for n, frame in by_slot.items() if frame.fixed_tool]
    if fixed:
        sentences.append(
            f"base(s) {', '.join(fixed)} are external TCPs (BASE_TYPE #TCP): move with "
            "$IPO_MODE #TCP and the part's gripper as the tool"
        )
    return sentences


def read(text: str) -> list[ParsedFrame]:
    """Every BASE_DATA[n] of $config.dat text, with its BASE_NAME and BASE_TYPE (#TCP a fixed
    tool, #BASE a base, #NONE or none: not said)."""
    names = {int(m.group(1)): m.group(2).strip() or None for m in _NAME.finditer(text)}
    types = {int(m.group(1)): m.group(2).upper() for m in _TYPE.finditer(text)}
    frames = []
    for match in _ASSIGNMENT.finditer(text):
        slot = int(match.group(1))
        position, quaternion = parse(match.group(0))
        kind = types.get(slot)
        fixed = {EXTERNAL_TCP_TYPE: True, BASE_TYPE: False}.get(kind or "")
        frames.append(ParsedFrame(slot, names.get(slot), position, quaternion, fixed))
    if not frames:
        raise parse_error(FORMAT, "BASE_DATA[n]={X x,Y y,Z z,A a,B b,C c} lines", text)
    return frames
