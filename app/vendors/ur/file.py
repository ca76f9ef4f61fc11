"""Universal Robots: a URScript file with a function per tool that sets its TCP and payload.

Followed: Universal Robots *The URScript Programming Language* (e-Series, 5.x), "set_tcp(pose)"
(a pose p[x, y, z, rx, ry, rz]: metres and a rotation vector in radians), "set_payload(m,
cog)" (kg, centre of gravity in metres in the tool flange frame), "Functions" (``def
name(): ... end``, identifiers of letters, digits and underscores starting with a letter) and
comments (``#`` to the end of the line). Load the file in a Script node (File) of the robot
program, or send it to the secondary interface, then call ``tcpcal_<tool>()`` where the tool
is taken up. A tool without a load gets no set_payload (the payload in use is kept).

What it changes, and how the controller merges it: loading the file defines functions and
changes nothing; calling one sets the TCP (and payload) of the running program until it
ends (a script-set TCP lasts until a program is played again: UR's payload article). The
installation's TCPs and every other tool are untouched. Its header comment says so.

How it relates to the live deploy (``ur_rtde``, app.vendors.ur.rtde): a deployment sends the
same ``set_tcp`` (and ``set_payload``) as a secondary program, so the robot moves by the
version at once, and only until the next program start, which sets the installation's TCP
again (deployment ``scope: "live"``). This file is what persists: a program that calls
``tcpcal_<tool>()`` at its start sets the version at every start, and the reconcile rounds
then find the robot moving by it. Deploy to switch now; put the file in the program to keep
it.
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
from app.vendors.names import identifier, unique
from app.vendors.text import (
    KG_DECIMALS,
    NUMBER,
    SI_DECIMALS,
    fmt_list,
    fmt_number,
    parse_error,
)
from app.vendors.tool import ToolData
from app.vendors.ur.text import export, parse

FORMAT = "ur"
PREFIX = "tcpcal_"
NAME_CHARS = 40
LINE_WIDTH = 78

_DEF = re.compile(r"^\s*def\s+([A-Za-z][A-Za-z0-9_]*)\s*\(\s*\)\s*:", re.MULTILINE)
# set_payload(m, cog), or set_target_payload(m, cog, inertia) as PolyScope 5.10+ writes a
# program's payload (URScript manual; a PolyScope-saved .script in tests/data/controller-files).
_PAYLOAD = re.compile(
    rf"set_(?:target_)?payload\(\s*({NUMBER})\s*,\s*\[\s*({NUMBER})\s*,\s*({NUMBER})\s*,"
    rf"\s*({NUMBER})\s*\]"
)


def function_name(name: str) -> str:
    """tcpcal_<tool name as an identifier>, at most 40 characters."""
    return PREFIX + identifier(name, NAME_CHARS - len(PREFIX), fallback="tool")


def _body(tool: ToolData) -> list[str]:
    pose = export(tool).values["pose"]
    assert isinstance(pose, list)
    lines = [f"  set_tcp(p[{fmt_list([float(v) for v in pose], SI_DECIMALS)}])"]
    if tool.load is not None and tool.load.mass_kg > 0:
        cog_m = np.asarray(tool.load.cog_or_origin) / 1000.0
        mass = fmt_number(tool.load.mass_kg, KG_DECIMALS)
        lines.append(f"  set_payload({mass}, [{fmt_list(cog_m, SI_DECIMALS)}])")
    return lines


def write(tools: list[FileTool], context: FileContext) -> ControllerFile:
    """Header comments, then ``def tcpcal_<tool>(): set_tcp(..) set_payload(..) end`` each."""
    kept, left = split_fitting(tools, export, context)
    names = unique([function_name(item.data.name) for item in kept], NAME_CHARS)
    lines = header_comments(kept, left, context, _how(names), "# ", LINE_WIDTH)
    for item, name in zip(kept, names, strict=True):
        lines += [f"def {name}():", *_body(item.data), "end"]
    file_name = "tcpcal_tools.script" if context.table or len(kept) != 1 else f"{names[0]}.script"
    return ControllerFile(FORMAT, file_name, "\n".join(lines) + "\n", tuple(left))


def _how(names: list[str]) -> list[str]:
    """The header's sentences on what the file changes."""
    if not names:
        return ["changes nothing: it holds no tool"]
    return [
        f"defines {', '.join(f'{n}()' for n in names)} and changes nothing until one is "
        "called: a call sets the TCP (and payload) of the running program until it ends",
        "the installation's TCPs and every other tool are untouched",
    ]


def read(text: str) -> list[ParsedTool]:
    """Every function's set_tcp (and set_payload) of a URScript file."""
    starts = list(_DEF.finditer(text))
    tools = []
    for i, match in enumerate(starts):
        end = starts[i + 1].start() if i + 1 < len(starts) else len(text)
        body = text[match.end() : end]
        position, quaternion = parse(body)
        payload = _PAYLOAD.search(body)
        mass = float(payload.group(1)) if payload else None
        cog = np.array([float(g) for g in payload.groups()[1:]]) * 1000.0 if payload else None
        tools.append(ParsedTool(None, match.group(1), position, quaternion, mass, cog))
    if not tools:
        raise parse_error(FORMAT, "def tcpcal_<tool>(): set_tcp(p[...]) ... end", text)
    return tools
