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

What it changes, and how the controller merges it: only the tooldata of the tools it holds;
no other data, routine or tool of the controller. A tool with a ``controller_symbol``
("T_ROB1/user/tTorch") is named by its SYMBOL, the persistent the robot's programs move by, and
is not declared again: its module (``user``) declares it. A tool without one is declared here
(``PERS tooldata <name>``). Loading a module need not change a persistent already in use: a
persistent declared in several modules is one object (RAPID overview, "Persistents"), and which
declaration's initial value it then holds is not something a file should rely on; not
declaring it at all (a controller_symbol's tool) changes nothing on loading. So the module
holds a routine,
``tcpcal_set_<tools|tool>``, that assigns each tool's value: load the module into the tool's
task (FlexPendant: Program Editor -> Modules -> Load Module, or RobotStudio), run the routine
once (PP to Routine). A module of the same name loaded before is tcpcal's own and is replaced.
The inertia is written as 0 (tcpcal stores mass and centre of gravity only: a point load,
which RAPID accepts).
"""

from __future__ import annotations

import re

import numpy as np

from app.vendors.abb.text import (
    MAX_IDENTIFIER,
    RapidSyntaxError,
    export,
    rapid_identifier,
    rapid_name,
    tooldata_at,
    tooldata_value,
    unit_quaternion,
)
from app.vendors.files import (
    ControllerFile,
    FileContext,
    FileTool,
    LeftOut,
    ParsedTool,
    header_comments,
    split_fitting,
)
from app.vendors.names import unique
from app.vendors.text import parse_error

FORMAT = "abb"
#: Comment lines kept short enough for the FlexPendant's editor.
LINE_WIDTH = 78
TABLE_MODULE = "tcpcal_tools"

# A declaration (``PERS tooldata name:=[...]``, also TASK or LOCAL) or an assignment in a
# routine (``name:=[...]``): where a value starts; only a tooldata's is kept.
_ASSIGNED = re.compile(r"(?<![A-Za-z0-9_])([A-Za-z][A-Za-z0-9_]*)\s*:=\s*(?=\[)")
_MODULE = re.compile(r"^\s*MODULE\s+([A-Za-z][A-Za-z0-9_]*)", re.IGNORECASE | re.MULTILINE)
_END = re.compile(r"^\s*ENDMODULE\s*$", re.IGNORECASE | re.MULTILINE)


def module_name(tools: list[FileTool], context: FileContext) -> str:
    """tcpcal_tools for a robot's table, tcpcal_<tool> for one tool (<= 32 characters)."""
    if context.table or len(tools) != 1:
        return TABLE_MODULE
    return rapid_identifier("tcpcal_" + rapid_identifier(tools[0].data.name))


def routine_name(module: str) -> str:
    """The routine that assigns the tools: tcpcal_set_tools, tcpcal_set_<tool>."""
    return rapid_identifier("tcpcal_set_" + module.removeprefix("tcpcal_"))


def _data_names(
    kept: list[FileTool], taken: list[str]
) -> tuple[list[FileTool], list[str], list[LeftOut]]:
    """(the tools, their tooldata names, the tools left out), in the tools' order: a
    controller_symbol's name as it is (it names data on the controller; renaming it would make
    a new persistent), the others' names made unique among all of them."""
    seen = {n.lower() for n in taken}
    symbol_names: dict[int, str] = {}
    left: list[LeftOut] = []
    for i, item in enumerate(kept):
        if item.data.controller_symbol:
            name = rapid_name(item.data)
            if name.lower() in seen:
                reason = f"another tool of this file has the tooldata name {name}"
                left.append(LeftOut(item.data.name, reason))
                continue
            seen.add(name.lower())
            symbol_names[i] = name
    plain = [i for i, item in enumerate(kept) if not item.data.controller_symbol]
    fixed = [*taken, *symbol_names.values()]
    made = unique(fixed + [rapid_name(kept[i].data) for i in plain], MAX_IDENTIFIER)
    names = {**symbol_names, **dict(zip(plain, made[len(fixed) :], strict=True))}
    order = sorted(names)
    return [kept[i] for i in order], [names[i] for i in order], left


def _how(tools: list[FileTool], names: list[str], routine: str) -> list[str]:
    """The header's sentences on what the module changes and how to load it."""
    if not tools:
        return ["changes nothing on the controller: it holds no tool"]
    held = []
    for item, name in zip(tools, names, strict=True):
        symbol = item.data.controller_symbol
        held.append(f"{name} ({symbol})" if symbol else f"{name} (declared here)")
    symbols = [t.data.controller_symbol for t in tools if t.data.controller_symbol]
    tasks = sorted({symbol.split("/")[0] for symbol in symbols})
    task = f"task {', '.join(tasks)}" if tasks else "the robot's motion task (e.g. T_ROB1)"
    return [
        f"changes only the tooldata {', '.join(held)}; every other tool and all other data "
        "of the controller are untouched",
        f"load it into {task} (Program Editor, Modules, Load Module), then run "
        f"{routine} once (PP to Routine): it assigns the values. Loading alone may leave a "
        "tooldata already in use as it was",
    ]


def write(tools: list[FileTool], context: FileContext) -> ControllerFile:
    """One RAPID module: a header comment, a PERS tooldata for each tool without a
    controller_symbol, and a routine assigning every tool's tooldata."""
    kept, left = split_fitting(tools, export, context)
    module = module_name(tools, context)
    routine = routine_name(module)
    held, names, clashes = _data_names(kept, [module, routine])
    left = [*left, *clashes]
    how = _how(held, names, routine)
    lines = [f"MODULE {module}", *header_comments(held, left, context, how, "  ! ", LINE_WIDTH)]
    for item, name in zip(held, names, strict=True):
        if not item.data.controller_symbol:
            lines.append(f"  PERS tooldata {name}:={tooldata_value(item.data)};")
    if held:
        lines.append(f"  PROC {routine}()")
        lines += [
            f"    {name}:={tooldata_value(item.data)};"
            for item, name in zip(held, names, strict=True)
        ]
        lines.append("  ENDPROC")
    lines.append("ENDMODULE")
    return ControllerFile(FORMAT, f"{module}.mod", "\n".join(lines) + "\n", tuple(left))


def read(text: str) -> list[ParsedTool]:
    """Every tooldata of a RAPID module (MODULE ... ENDMODULE around them), declared or
    assigned, once each by name (the last value written: what the module leaves)."""
    if _MODULE.search(text) is None or _END.search(text) is None:
        raise parse_error(FORMAT, "a RAPID module: MODULE <name> ... ENDMODULE", text)
    tools: dict[str, ParsedTool] = {}
    for match in _ASSIGNED.finditer(text):
        try:
            tool = tooldata_at(text, match.end())
        except RapidSyntaxError:
            continue  # another data type's value (a robtarget, a wobjdata), or not a value
        tools[match.group(1).lower()] = ParsedTool(
            slot=None,
            name=match.group(1),
            position_mm=np.array(tool.position_mm),
            quaternion_wxyz=unit_quaternion(tool.quaternion),
            mass_kg=tool.mass_kg,
            cog_mm=np.array(tool.cog_mm),
        )
    return list(tools.values())
