"""ABB: a RAPID program module holding each tool's PERS tooldata, load included.

Followed: ABB *Technical reference manual - RAPID Instructions, Functions and Data types*,
"tooldata" (robhold, tframe [trans mm, rot q1..q4 with q1 the scalar part], tload loaddata
[mass kg, cog mm, aom, ix, iy, iz kgm2]; the manual's example ``PERS tooldata gripper :=
[TRUE, [[97.4, 0, 223.1], [0.924, 0, 0.383 ,0]], [5, [23, 0, 75], [1, 0, 0, 0], 0, 0, 0]];``)
and *Technical reference manual - RAPID overview*, "Basic elements" (identifiers: a letter,
then letters, digits or underscores, at most 32 characters; comments start with ``!`` and run
to the end of the line) and "Modules" (``MODULE name ... ENDMODULE``). Public modules in the
same shape: RobotStudio exports and robot cells' sources on GitHub, e.g. the
``MODULE ... PERS tooldata tGripper:=[TRUE,[[0.51636,-0.710444,275.457],[1,0,0,0]],
[26,[80,0,180],[1,0,0,0],0,0,0]];`` modules found with the code search of issue 27.

Load it with the FlexPendant's Program Editor (Modules -> File -> Load module) or RobotStudio;
it declares no routine, so it runs nothing. A persistent that another loaded module already
declares with the same name is one and the same object in RAPID: the module's value then
does not replace the one in use (RAPID overview, "Persistents"), so remove or rename the old
declaration first. The inertia is written as 0 (tcpcal stores mass and centre of gravity
only: a point load, which RAPID accepts).
"""

from __future__ import annotations

import re

import numpy as np

from app.exports.abb import MAX_IDENTIFIER, export_abb, rapid_identifier
from app.exports.base import NUMBER, parse_error
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
from app.exports.names import unique
from app.solvers.validation import normalised_quaternions

FORMAT = "abb"
#: Comment lines kept short enough for the FlexPendant's editor.
LINE_WIDTH = 78
TABLE_MODULE = "tcpcal_tools"

_N = rf"\s*({NUMBER})\s*"
_TOOLDATA = re.compile(
    r"PERS\s+tooldata\s+([A-Za-z][A-Za-z0-9_]*)\s*:=\s*\[\s*(TRUE|FALSE)\s*,"
    rf"\s*\[\s*\[{_N},{_N},{_N}\]\s*,\s*\[{_N},{_N},{_N},{_N}\]\s*\]\s*,"
    rf"\s*\[{_N},\s*\[{_N},{_N},{_N}\]",
    re.IGNORECASE,
)
_MODULE = re.compile(r"^\s*MODULE\s+([A-Za-z][A-Za-z0-9_]*)", re.IGNORECASE | re.MULTILINE)
_END = re.compile(r"^\s*ENDMODULE\s*$", re.IGNORECASE | re.MULTILINE)


def module_name(tools: list[FileTool], context: FileContext) -> str:
    """tcpcal_tools for a robot's table, tcpcal_<tool> for one tool (<= 32 characters)."""
    if context.table or len(tools) != 1:
        return TABLE_MODULE
    return rapid_identifier("tcpcal_" + rapid_identifier(tools[0].data.name))


def write(tools: list[FileTool], context: FileContext) -> ControllerFile:
    """One RAPID module: a header comment, then a PERS tooldata per tool."""
    kept, left = split_fitting(tools, export_abb, context)
    module = module_name(tools, context)
    names = unique([module] + [rapid_identifier(item.data.name) for item in kept], MAX_IDENTIFIER)[
        1:
    ]
    lines = [f"MODULE {module}"]
    for sentence in header_lines(kept, context) + left_out_lines(left):
        lines.extend(f"  ! {piece}" for piece in wrap(sentence, LINE_WIDTH - 4))
    for item, name in zip(kept, names, strict=True):
        text = export_abb(item.data).text
        lines.append(
            "  " + re.sub(r"^PERS tooldata [A-Za-z0-9_]+:=", f"PERS tooldata {name}:=", text)
        )
    lines.append("ENDMODULE")
    return ControllerFile(FORMAT, f"{module}.mod", "\n".join(lines) + "\n", tuple(left))


def read(text: str) -> list[ParsedTool]:
    """Every PERS tooldata of a RAPID module (MODULE ... ENDMODULE around them)."""
    if _MODULE.search(text) is None or _END.search(text) is None:
        raise parse_error(FORMAT, "a RAPID module: MODULE <name> ... ENDMODULE", text)
    tools = []
    for match in _TOOLDATA.finditer(text):
        numbers = [float(g) for g in match.groups()[2:]]
        quaternion = normalised_quaternions(np.array([numbers[3:7]]), loc=("text",))[0]
        tools.append(
            ParsedTool(
                slot=None,
                name=match.group(1),
                position_mm=np.array(numbers[:3]),
                quaternion_wxyz=quaternion,
                mass_kg=numbers[7],
                cog_mm=np.array(numbers[8:11]),
            )
        )
    return tools
