"""KUKA: the tool's lines of ``KRC:\\R1\\System\\$config.dat`` as KSS declares them.

Followed: KUKA System Software 8.x *Operating and Programming Instructions for System
Integrators*, "FRAME" (X Y Z mm, A B C deg, R = Rz(A) Ry(B) Rx(C)) and "LOAD" (M kg,
CM the centre of mass frame relative to the flange, J the moments of inertia kg m2; M -1
means "no load data: use the default"), and real $config.dat files of KSS 8 controllers in
public robot-cell repositories (e.g. EdgarMontielG/Cell-3_R10 KRC/R1/System/$config.dat),
which declare the tool table as::

    INT MAX_TOOL=16
    DECL FRAME TOOL_DATA[16]
    TOOL_DATA[1]={X 0.0,Y 0.0,Z 380.790,A -90.0000,B -90.0000,C -90.0000}
    DECL CHAR TOOL_NAME[16,24]
    TOOL_NAME[1,]="TOOL 1"          (" " for an unused tool)
    DECL LOAD LOAD_DATA[16]
    LOAD_DATA[1]={M 210.000,CM {X 270.000,Y 0.0,Z 240.000,A 0.0,B 0.0,C 0.0},J {X 105.000,...}}
    (LOAD_DATA[4]={M -1.00000,CM {X 0.0,...},J {X 0.0,Y 0.0,Z 0.0}} for an unused tool)

Comments start with ``;``. TOOL_NAME is CHAR[24]: at most 24 characters, none of them a
double quote. One tool's file is its three lines (replace the lines of the same tool number
in $config.dat); a robot's table is the three whole arrays, tools tcpcal does not hold
written as KSS writes unused ones (replace the three arrays). The numbers are those of the
JSON ``controller.text`` (``$TOOL_DATA[n]`` as KUKAVARPROXY reads it; the $config.dat line
drops the ``$``).
"""

from __future__ import annotations

import re

import numpy as np

from app.exports.base import (
    KG_DECIMALS,
    MM_DECIMALS,
    NUMBER,
    ToolData,
    fmt_number,
    parse_error,
)
from app.exports.files import (
    ControllerFile,
    FileContext,
    FileTool,
    ParsedTool,
    header_lines,
    left_out_lines,
    split_fitting,
    wrap,
)
from app.exports.kuka import MAX_SLOT, export_kuka, parse_kuka
from app.exports.names import ascii_text, file_stem

FORMAT = "kuka"
NAME_CHARS = 24
LINE_WIDTH = 78
_UNUSED_FRAME = "{X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}"
_UNUSED_LOAD = "{M -1.0,CM {X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0},J {X 0.0,Y 0.0,Z 0.0}}"

_N = rf"\s*({NUMBER})\s*"
_TOOL_DATA = re.compile(r"^\s*\$?TOOL_DATA\[\s*(\d+)\s*\]\s*=.*$", re.IGNORECASE | re.MULTILINE)
_TOOL_NAME = re.compile(
    r'^\s*\$?TOOL_NAME\[\s*(\d+)\s*,\s*\]\s*=\s*"([^"]*)"', re.IGNORECASE | re.MULTILINE
)
_LOAD_DATA = re.compile(
    rf"^\s*\$?LOAD_DATA\[\s*(\d+)\s*\]\s*=\s*\{{\s*M{_N},\s*CM\s*\{{\s*X{_N},\s*Y{_N},\s*Z{_N},",
    re.IGNORECASE | re.MULTILINE,
)


def tool_name(name: str) -> str:
    """A TOOL_NAME value: printable ASCII without double quotes, at most 24 characters."""
    return ascii_text(name, NAME_CHARS, drop='"') or " "


def frame_value(tool: ToolData) -> str:
    """``{X ..,Y ..,Z ..,A ..,B ..,C ..}``: the JSON text's numbers."""
    return export_kuka(tool).text.split("=", 1)[1]


def load_value(tool: ToolData) -> str:
    """``{M ..,CM {X ..,Y ..,Z ..,A 0.0,B 0.0,C 0.0},J {X 0.0,Y 0.0,Z 0.0}}`` (M -1 without a
    load: the controller's default)."""
    if tool.mass_kg is None:
        return _UNUSED_LOAD
    cog = tool.cog_mm if tool.cog_mm is not None else np.zeros(3)
    x, y, z = (fmt_number(c, MM_DECIMALS) for c in cog)
    mass = fmt_number(tool.mass_kg, KG_DECIMALS)
    return f"{{M {mass},CM {{X {x},Y {y},Z {z},A 0.0,B 0.0,C 0.0}},J {{X 0.0,Y 0.0,Z 0.0}}}}"


def write(tools: list[FileTool], context: FileContext) -> ControllerFile:
    """A tool's three $config.dat lines, or a robot's three arrays."""
    kept, left = split_fitting(tools, export_kuka, context)
    lines: list[str] = []
    for sentence in header_lines(kept, context) + left_out_lines(left) + [_how(context)]:
        lines.extend(f"; {piece}" for piece in wrap(sentence, LINE_WIDTH - 2))
    by_slot = {item.data.slot: item.data for item in kept}
    if context.table:
        lines.extend(_arrays(by_slot))
    else:
        for tool in by_slot.values():
            lines.append(f"TOOL_DATA[{tool.slot}]={frame_value(tool)}")
            lines.append(f'TOOL_NAME[{tool.slot},]="{tool_name(tool.name)}"')
            lines.append(f"LOAD_DATA[{tool.slot}]={load_value(tool)}")
    if context.table:
        name = "config_tools.dat"
    else:
        name = f"tool{kept[0].data.slot}_{file_stem(kept[0].data.name)}.dat"
    return ControllerFile(FORMAT, name, "\n".join(lines) + "\n", tuple(left))


def _how(context: FileContext) -> str:
    if context.table:
        return (
            "replaces DECL FRAME TOOL_DATA, DECL CHAR TOOL_NAME and DECL LOAD LOAD_DATA "
            "in KRC:\\R1\\System\\$config.dat"
        )
    return "replaces this tool's lines in KRC:\\R1\\System\\$config.dat"


def _arrays(by_slot: dict[int | None, ToolData]) -> list[str]:
    slots = range(1, MAX_SLOT + 1)
    lines = [f"DECL FRAME TOOL_DATA[{MAX_SLOT}]"]
    lines += [
        f"TOOL_DATA[{n}]={frame_value(by_slot[n]) if n in by_slot else _UNUSED_FRAME}"
        for n in slots
    ]
    lines.append(f"DECL CHAR TOOL_NAME[{MAX_SLOT},{NAME_CHARS}]")
    lines += [
        f'TOOL_NAME[{n},]="{tool_name(by_slot[n].name) if n in by_slot else " "}"' for n in slots
    ]
    lines.append(f"DECL LOAD LOAD_DATA[{MAX_SLOT}]")
    lines += [
        f"LOAD_DATA[{n}]={load_value(by_slot[n]) if n in by_slot else _UNUSED_LOAD}" for n in slots
    ]
    return lines


def read(text: str) -> list[ParsedTool]:
    """Every TOOL_DATA[n] of $config.dat text, with its TOOL_NAME and LOAD_DATA."""
    names = {int(m.group(1)): m.group(2).strip() or None for m in _TOOL_NAME.finditer(text)}
    loads = {int(m.group(1)): [float(g) for g in m.groups()[1:]] for m in _LOAD_DATA.finditer(text)}
    tools = []
    for match in _TOOL_DATA.finditer(text):
        slot = int(match.group(1))
        position, quaternion = parse_kuka(match.group(0))
        load = loads.get(slot)
        has_mass = load is not None and load[0] >= 0
        tools.append(
            ParsedTool(
                slot=slot,
                name=names.get(slot),
                position_mm=position,
                quaternion_wxyz=quaternion,
                mass_kg=load[0] if load is not None and has_mass else None,
                cog_mm=np.array(load[1:]) if load is not None and has_mass else None,
            )
        )
    if not tools:
        raise parse_error(FORMAT, "TOOL_DATA[n]={X x,Y y,Z z,A a,B b,C c} lines", text)
    return tools
