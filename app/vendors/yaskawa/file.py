"""Yaskawa: TOOL.CND, the tool file as the controller saves and loads it.

Followed: TOOL.CND files of controller backups in public repositories (DX100/FS100
SinaiAranda/motoman_sda20d_sys TOOL.CND; DX200 lukelalondePZ/Fiberdome-GP88-Spindle-Cell
TOOL.CND; YRC1000 lukelalondePZ/Komatsu-Press-Demo TOOL.CND), each tool a block::

    //TOOL 0
    ///NAME STANDARD TOOL
    0.000,0.000,0.000,0.0000,90.0000,0.0000      X Y Z (mm, 3 decimals), Rx Ry Rz (deg, 4)
    -16.507,-21.039,-136.477                      centre of gravity Xg Yg Zg (mm, flange)
    104.011                                       mass W (kg)
    0.000,0.000,0.000                             moments of inertia Ix Iy Iz (kg m2)
    0.000,0,1                                     (not described publicly: written as the
                                                   backups write it for a tool set by hand)

and the Yaskawa manuals' "Tool Load Information ... registered in the tool file" (W, Xg, Yg,
Zg; Ix, Iy, Iz) for the meaning of lines 2-4. Rx Ry Rz are the fixed-axis angles of
app.vendors.wpr (R = Rz Ry Rx). YRC1000 backups carry a ``///CRC`` line per block whose
algorithm is not public: a written block leaves it out, as the DX100/DX200 files have none, and
`merge` keeps the controller's own line (the public YRC1000 backup has the same value in every
block, whatever its numbers).

A condition file has no comment syntax: nothing but the blocks can be in it, so this file has
no header (tool, version, calibration), only each tool's ``///NAME`` (at most 16 characters,
ASCII, no comma). A robot's table holds the blocks of the tools tcpcal has (by tool number,
0-63); the controller's other tools are not written.

What it changes: loading TOOL.CND (EX. MEMORY -> LOAD -> CONDITION DATA -> TOOL DATA) loads the
controller's whole tool file, and a controller's own TOOL.CND holds a block for every tool
number (the backups above: 64 blocks, 0-63). Loaded as it is, this file, which holds only
tcpcal's tools, may clear or refuse the others: it cannot say so itself, so the docs
(docs/controller-files.md) and the CLI say it. What merges: `merge` puts its blocks in place of
the same numbers' blocks of the controller's own TOOL.CND (saved from the controller first),
every other byte kept (``tcpcal export ... --format yaskawa --merge-into SAVED.CND``); that
file changes only tcpcal's tools when loaded. (A deployment over HSES does the same with the
file it reads from the controller.)
"""

from __future__ import annotations

import re

import numpy as np

from app.errors import InvalidInput
from app.vendors.files import ControllerFile, FileContext, FileTool, ParsedTool, split_fitting
from app.vendors.names import ascii_text
from app.vendors.text import NUMBER, parse_error
from app.vendors.tool import ToolData
from app.vendors.wpr import check_slot, tcp_from_numbers, xyz_wpr
from app.vendors.yaskawa import TOOL_NUMBERS

FORMAT = "yaskawa"
NAME_CHARS = 16
MM_DECIMALS = 3
DEG_DECIMALS = 4
#: What a TOOL.CND of tcpcal's tools changes, said beside it as it has no comment syntax: the
#: CLI prints it after an export and writes it beside a backup's TOOL.CND.
WHOLE_FILE_NOTE = (
    "TOOL.CND holds only the tools tcpcal manages, and loading TOOL.CND loads the controller's "
    "whole tool file: loaded as it is, it may clear the other tools. Save the controller's own "
    "TOOL.CND, then `tcpcal export TOOL --format yaskawa --merge-into SAVED.CND` (or copy "
    "these //TOOL n blocks over the same numbers' blocks) and load that."
)
_UNKNOWN_LAST_LINE = "0.000,0,1"

_N = rf"\s*({NUMBER})\s*"
_BLOCK = re.compile(
    r"^//TOOL\s+(\d+)\s*\n(?:///(?!NAME)[^\n]*\n)*///NAME ?([^\n]*)\n"
    rf"{_N},{_N},{_N},{_N},{_N},{_N}\n{_N},{_N},{_N}\n{_N}\n",
    re.MULTILINE,
)


def check_tool(tool: ToolData) -> None:
    """A Yaskawa tool needs its tool number (0-63): InvalidInput otherwise."""
    if tool.slot is None:
        raise InvalidInput(
            "invalid-options",
            "a Yaskawa tool needs its tool number (slot 0..63) for TOOL.CND; it has none: "
            "set the tool's slot",
            loc=("slot",),
        )
    check_slot(FORMAT, tool.slot, TOOL_NUMBERS)
    xyz_wpr(tool)


def tool_name(name: str) -> str:
    """A ///NAME value: ASCII, no comma, at most 16 characters."""
    return ascii_text(name, NAME_CHARS, drop=",")


def _fixed(value: float, decimals: int) -> str:
    return f"{round(float(value), decimals) + 0.0:.{decimals}f}"


def block(tool: ToolData) -> list[str]:
    """One tool's seven lines."""
    numbers = xyz_wpr(tool)
    pose = [_fixed(v, MM_DECIMALS) for v in numbers[:3]]
    pose += [_fixed(v, DEG_DECIMALS) for v in numbers[3:]]
    cog = tool.load.cog_or_origin if tool.load is not None else (0.0, 0.0, 0.0)
    mass = tool.load.mass_kg if tool.load is not None else 0.0
    return [
        f"//TOOL {tool.slot}",
        f"///NAME {tool_name(tool.name)}".rstrip(),
        ",".join(pose),
        ",".join(_fixed(c, MM_DECIMALS) for c in cog),
        _fixed(mass, MM_DECIMALS),
        "0.000,0.000,0.000",
        _UNKNOWN_LAST_LINE,
    ]


def write(tools: list[FileTool], context: FileContext) -> ControllerFile:
    """The tools' blocks by tool number."""
    kept, left = split_fitting(tools, check_tool, context)
    lines: list[str] = []
    for item in sorted(kept, key=lambda t: t.data.slot or 0):
        lines += block(item.data)
    text = "\n".join(lines) + "\n" if lines else ""
    return ControllerFile(FORMAT, "TOOL.CND", text, tuple(left))


_BLOCK_START = re.compile(r"^//TOOL\s+(\d+)\s*$", re.MULTILINE)


def _blocks(text: str) -> dict[int, tuple[int, int]]:
    """Tool number -> (start, end) of its block in `text` (a block runs to the next one)."""
    starts = list(_BLOCK_START.finditer(text))
    ends = [m.start() for m in starts[1:]] + [len(text)]
    return {int(m.group(1)): (m.start(), end) for m, end in zip(starts, ends, strict=True)}


def merge(saved: str, ours: str) -> str:
    """The controller's own TOOL.CND `saved` with each block of `ours` in place of the block of
    the same tool number; every other byte as it was. InvalidInput when `saved` is not a tool
    file or lacks one of the tool numbers (a controller's file holds every number)."""
    saved = saved.replace("\r\n", "\n")
    mine = {n: ours[a:b] for n, (a, b) in _blocks(ours.replace("\r\n", "\n")).items()}
    theirs = _blocks(saved)
    if not theirs:
        raise parse_error(FORMAT, "the controller's TOOL.CND (//TOOL 0 ... //TOOL 63)", saved)
    missing = sorted(set(mine) - set(theirs))
    if missing:
        raise InvalidInput(
            "invalid-pose",
            f"the saved TOOL.CND has no block for tool(s) {missing}: save the tool file of "
            "the robot's own controller (it holds every tool number) and merge into that",
            loc=("text",),
        )
    out, at = [], 0
    for number, (start, end) in sorted(theirs.items(), key=lambda kv: kv[1][0]):
        if number in mine:
            out += [saved[at:start], _with_crc(mine[number], saved[start:end])]
            at = end
    return "".join(out) + saved[at:]


_CRC = re.compile(r"^///CRC[^\n]*\n", re.MULTILINE)


def _with_crc(ours: str, theirs: str) -> str:
    """Our block with the ``///CRC`` line the controller's own block has (YRC1000 files), kept
    as it was: its algorithm is not public, and the public YRC1000 backup carries one value in
    every block whatever the numbers (so it is not a checksum of the block's numbers)."""
    crc = _CRC.search(theirs)
    if crc is None or _CRC.search(ours):
        return ours
    head, _, rest = ours.partition("\n")
    return f"{head}\n{crc.group(0)}{rest}"


def read(text: str) -> list[ParsedTool]:
    """Every //TOOL block of a TOOL.CND text."""
    tools = []
    for match in _BLOCK.finditer(text.replace("\r\n", "\n")):
        numbers = [float(g) for g in match.groups()[2:]]
        position, quaternion = tcp_from_numbers(numbers[:6])
        mass = numbers[9]
        tools.append(
            ParsedTool(
                slot=int(match.group(1)),
                name=match.group(2).strip() or None,
                position_mm=position,
                quaternion_wxyz=quaternion,
                mass_kg=mass if mass > 0 else None,
                cog_mm=np.array(numbers[6:9]) if mass > 0 else None,
            )
        )
    if not tools:
        raise parse_error(FORMAT, "TOOL.CND blocks (//TOOL n, ///NAME, X,Y,Z,Rx,Ry,Rz ...)", text)
    return tools
