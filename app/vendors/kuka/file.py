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
double quote.

What it changes, and how the controller merges it: a file (one tool's or a robot's table)
holds, for each tool tcpcal manages, its array elements as single-element assignments,
``TOOL_DATA[n]=...``, ``TOOL_NAME[n,]=...`` and, when tcpcal knows the tool's load,
``LOAD_DATA[n]=...``: the lines $config.dat initialises each element with, one element each.
Replace the lines of the same numbers in $config.dat with them (the ``DECL`` lines and every
other tool's lines stay as they are), or run them as assignments in a KRL program. Never the
whole arrays: $config.dat holds all 16 tools, most of them other people's, and an array
written whole would set the tools tcpcal does not manage to zeros, ``M -1`` and ``" "``. A
tool without a known load gets no LOAD_DATA line (the controller's load data stays). The
numbers are those of the JSON ``controller.text`` (``$TOOL_DATA[n]`` as KUKAVARPROXY reads
it; the $config.dat line drops the ``$``).
"""

from __future__ import annotations

import re

import numpy as np

from app.vendors.files import (
    ControllerFile,
    FileContext,
    FileTool,
    ParsedTool,
    header_comments,
    split_fitting,
)
from app.vendors.kuka.text import export, parse
from app.vendors.names import ascii_text, file_stem
from app.vendors.text import KG_DECIMALS, MM_DECIMALS, NUMBER, fmt_number, parse_error
from app.vendors.tool import ToolData

FORMAT = "kuka"
NAME_CHARS = 24
LINE_WIDTH = 78

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
    return export(tool).text.split("=", 1)[1]


def load_value(tool: ToolData) -> str | None:
    """``{M ..,CM {X ..,Y ..,Z ..,A 0.0,B 0.0,C 0.0},J {X 0.0,Y 0.0,Z 0.0}}``; None without a
    known mass (the controller's load data is left as it is)."""
    if tool.load is None:
        return None
    x, y, z = (fmt_number(c, MM_DECIMALS) for c in tool.load.cog_or_origin)
    mass = fmt_number(tool.load.mass_kg, KG_DECIMALS)
    return f"{{M {mass},CM {{X {x},Y {y},Z {z},A 0.0,B 0.0,C 0.0}},J {{X 0.0,Y 0.0,Z 0.0}}}}"


def write(tools: list[FileTool], context: FileContext) -> ControllerFile:
    """Each tool's TOOL_DATA[n], TOOL_NAME[n,] (and LOAD_DATA[n]) line, by tool number."""
    kept, left = split_fitting(tools, export, context)
    by_slot = {item.data.slot: item.data for item in sorted(kept, key=lambda t: t.data.slot or 0)}
    lines = header_comments(kept, left, context, _how(by_slot), "; ", LINE_WIDTH)
    for slot, tool in by_slot.items():
        lines.append(f"TOOL_DATA[{slot}]={frame_value(tool)}")
        lines.append(f'TOOL_NAME[{slot},]="{tool_name(tool.name)}"')
        load = load_value(tool)
        if load is not None:
            lines.append(f"LOAD_DATA[{slot}]={load}")
    if context.table:
        name = "config_tools.dat"
    else:
        name = f"tool{kept[0].data.slot}_{file_stem(kept[0].data.name)}.dat"
    return ControllerFile(FORMAT, name, "\n".join(lines) + "\n", tuple(left))


def _how(by_slot: dict[int | None, ToolData]) -> list[str]:
    """The header's sentences on what the file changes and how it is applied."""
    if not by_slot:
        return ["changes nothing on the controller: it holds no tool"]
    numbers = ", ".join(str(n) for n in by_slot)
    unloaded = [str(n) for n, tool in by_slot.items() if load_value(tool) is None]
    sentences = [
        f"changes only tool(s) {numbers}: their TOOL_DATA, TOOL_NAME and LOAD_DATA elements; "
        "every other tool is untouched",
        "replace the lines of the same numbers in KRC:\\R1\\System\\$config.dat with these "
        "(keep the DECL lines and every other line), or run them as KRL assignments",
    ]
    if unloaded:
        sentences.append(
            f"no load known for tool(s) {', '.join(unloaded)}: no LOAD_DATA line, the "
            "controller's load data stays"
        )
    return sentences


def read(text: str) -> list[ParsedTool]:
    """Every TOOL_DATA[n] of $config.dat text, with its TOOL_NAME and LOAD_DATA."""
    names = {int(m.group(1)): m.group(2).strip() or None for m in _TOOL_NAME.finditer(text)}
    loads = {int(m.group(1)): [float(g) for g in m.groups()[1:]] for m in _LOAD_DATA.finditer(text)}
    tools = []
    for match in _TOOL_DATA.finditer(text):
        slot = int(match.group(1))
        position, quaternion = parse(match.group(0))
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
