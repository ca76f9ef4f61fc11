"""Techman: a frame as the TMscript line ``ChangeBase({X,Y,Z,RX,RY,RZ})`` (mm, deg), for a TMflow
SET or Script node (the text, and the file: one line per frame under a comment naming it),
and their reader.

Followed: the TMflow *Expression Editor and Listen Node* manual, ``ChangeBase`` (section
9.13): ``ChangeBase("name")`` selects a base of the project's list, ``ChangeBase`` with the
six values sets the current base by them, X Y Z in mm and RX RY RZ in deg in the robot base,
taken as app.vendors.wpr's fixed-axis angles as the tool's ChangeTCP is
(app.vendors.techman.text, with what is and is not verified). The line is the array form
``ChangeBase({X,Y,Z,RX,RY,RZ})`` the connector sends (app.vendors.techman.tmflow) and the
tool's ChangeTCP uses (TMscript array literals are braces); the reader also takes the six
flat. Numbers as the tool text prints them (6 decimals mm, 7 deg, trailing zeros dropped);
comments are ``//``.

What it changes, and how the controller merges it: a ChangeBase line, run by the flow, sets
the current base of the running project until it sets another; the project's base list is
untouched. A fixed tool has no line: TMflow has no stationary TCP (422 naming the frame's
kind; a robot's table names it in its header, left out).
"""

from __future__ import annotations

import re

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.vendors.files import ControllerFile, FileContext, header_comments, split_fitting
from app.vendors.frame import NOUN, FileFrame, FrameData, ParsedFrame
from app.vendors.names import ascii_text, file_stem
from app.vendors.techman.file import LINE_WIDTH
from app.vendors.techman.text import FORMAT, LABELS
from app.vendors.text import NUMBER, ControllerExport, fmt_number, parse_error
from app.vendors.wpr import DECIMALS, named_values, tcp_from_numbers, xyz_wpr

_SIX = r"\s*,\s*".join([f"({NUMBER})"] * 6)
# Braces around the six, or none; then the closing parenthesis.
_CALL = re.compile(rf"ChangeBase\s*\(\s*(\{{)?\s*{_SIX}\s*(?(1)\}})\s*\)")


def base_only(frame: FrameData) -> None:
    """422 at "kind" for a fixed tool: TMflow has no stationary TCP (the Listen Node's
    functions change the current base and the TCP on the flange, none a stationary tool, as
    the connector app.vendors.techman.tmflow says)."""
    if frame.fixed_tool:
        raise InvalidInput(
            "invalid-options",
            f"frame {frame.name!r} is a fixed tool, and a Techman controller has no stationary "
            "TCP (ChangeBase sets a base, ChangeTCP the flange's TCP): register it as a base "
            "to use its pose as one",
            loc=("kind",),
        )


def call(frame: FrameData) -> str:
    """``ChangeBase({X,Y,Z,RX,RY,RZ})`` of the frame (mm, deg), as the connector sends it;
    422 for a fixed tool."""
    base_only(frame)
    numbers = xyz_wpr(frame)
    values = ",".join(fmt_number(v, d) for v, d in zip(numbers, DECIMALS, strict=True))
    return f"ChangeBase({{{values}}})"


def _comment(frame: FrameData) -> str:
    return ascii_text(frame.name, 40) or NOUN


def export(frame: FrameData) -> ControllerExport:
    """``ChangeBase({X,Y,Z,RX,RY,RZ})  // name``; 422 for a fixed tool."""
    values: dict[str, object] = {"slot": frame.slot, **named_values(LABELS, xyz_wpr(frame))}
    return ControllerExport(
        format=FORMAT, text=f"{call(frame)}  // {_comment(frame)}", values=values
    )


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """``ChangeBase({X,Y,Z,RX,RY,RZ})`` or the six flat -> (position (3,) mm,
    quaternion wxyz (4,))."""
    match = _CALL.search(text)
    if match is None:
        raise parse_error(FORMAT, "ChangeBase({X,Y,Z,RX,RY,RZ})", text)
    return tcp_from_numbers([float(g) for g in match.groups()[1:]])


def write(frames: list[FileFrame], context: FileContext) -> ControllerFile:
    """Header comments, then per frame ``// <name>`` and its ChangeBase line."""
    kept, left = split_fitting(frames, call, context)
    lines = header_comments(kept, left, context, _how(kept), "// ", LINE_WIDTH, NOUN)
    for item in kept:
        lines += [f"// {_comment(item.data)}", call(item.data)]
    if context.table or len(kept) != 1:
        name = "tcpcal_bases.txt"
    else:
        name = f"tcpcal_base_{file_stem(kept[0].data.name)}.txt"
    return ControllerFile(FORMAT, name, "\n".join(lines) + "\n", tuple(left))


def _how(kept: list[FileFrame]) -> list[str]:
    """The header's sentences on what the lines change."""
    if not kept:
        return ["changes nothing: it holds no frame"]
    return [
        "each ChangeBase line, run by the flow, sets the current base of the running project "
        "until it sets another; the project's base list is untouched"
    ]


def read(text: str) -> list[ParsedFrame]:
    """Every ChangeBase line of the text, named by the comment above it."""
    frames = []
    name: str | None = None
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("//"):
            name = stripped[2:].strip() or None
            continue
        match = _CALL.search(line)
        if match is None:
            continue
        position, quaternion = tcp_from_numbers([float(g) for g in match.groups()[1:]])
        frames.append(ParsedFrame(None, name, position, quaternion))
        name = None
    if not frames:
        raise parse_error(FORMAT, "ChangeBase({X,Y,Z,RX,RY,RZ}) lines", text)
    return frames
