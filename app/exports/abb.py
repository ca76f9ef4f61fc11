"""ABB RAPID ``tooldata``: ``PERS tooldata name:=[TRUE,[[x,y,z],[q1,q2,q3,q4]],[load]];``.

Layout from the RAPID reference manual (tooldata: robhold, tframe = [trans mm,
rot quaternion q1..q4 with q1 the scalar part], tload = loaddata [mass kg, cog mm, aom,
ix, iy, iz kgm2]). The manual's example: ``PERS tooldata gripper := [TRUE, [[97.4, 0, 223.1],
[0.924, 0, 0.383, 0]], [5, [23, 0, 75], [1, 0, 0, 0], 0, 0, 0]];``. A held tool with mass 0
is refused by the controller when the tool is used in a move, so we refuse it here too, with
the reason, rather than hand out text that stops the robot later. Inertia is written as 0
(a point load), which RAPID accepts.
"""

from __future__ import annotations

import re

import numpy as np

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.exports.base import (
    KG_DECIMALS,
    MM_DECIMALS,
    NUMBER,
    QUATERNION_DECIMALS,
    ControllerExport,
    ToolData,
    checked_tcp,
    fmt_list,
    fmt_number,
    parse_error,
    rounded,
)
from app.exports.names import identifier
from app.solvers.validation import check_finite, normalised_quaternions

FORMAT = "abb"
#: RAPID identifiers: a letter, then letters, digits or underscores; at most 32 characters.
MAX_IDENTIFIER = 32
# fmt: off
# Names that cannot be (re)declared: RAPID reserved words used as data names here, and the
# predefined tool0 (system module BASE).
_RESERVED = {
    "and", "backward", "case", "connect", "const", "default", "div", "do", "else",
    "elseif", "endfor", "endfunc", "endif", "endmodule", "endproc", "endrecord",
    "endtest", "endtrap", "endwhile", "error", "exit", "false", "for", "from", "func",
    "goto", "if", "inout", "local", "mod", "module", "nostepin", "not", "noview", "or",
    "pers", "proc", "raise", "readonly", "record", "retry", "return", "step", "sysmodule",
    "test", "then", "to", "trap", "true", "trynext", "undo", "var", "viewonly", "while",
    "with", "xor", "tool0",
}
# fmt: on

_PATTERN = re.compile(
    r"tooldata\s+([A-Za-z][A-Za-z0-9_]*)\s*:=\s*\[\s*(TRUE|FALSE)\s*,\s*\[\s*\[\s*"
    rf"({NUMBER})\s*,\s*({NUMBER})\s*,\s*({NUMBER})\s*\]\s*,\s*\[\s*"
    rf"({NUMBER})\s*,\s*({NUMBER})\s*,\s*({NUMBER})\s*,\s*({NUMBER})\s*\]\s*\]",
    re.IGNORECASE,
)


def rapid_identifier(name: str) -> str:
    """`name` made a valid RAPID data name: [A-Za-z][A-Za-z0-9_]*, <= 32 chars, not reserved
    (accents taken off, other characters an underscore, "t" in front of a leading digit)."""
    return identifier(name, MAX_IDENTIFIER, fallback="t", reserved=_RESERVED)


def rapid_name(tool: ToolData) -> str:
    """The tooldata's data name: SYMBOL of the tool's controller_symbol "TASK/MODULE/SYMBOL"
    (the persistent the robot's programs move by), else the tool's name made an identifier."""
    if tool.controller_symbol:
        return rapid_identifier(tool.controller_symbol.rsplit("/", 1)[-1])
    return rapid_identifier(tool.name)


def tooldata_value(tool: ToolData) -> str:
    """``[TRUE,[[x,y,z],[q1..q4]],[mass,[cog],[1,0,0,0],0,0,0]]``: the tool's tooldata value."""
    position, quaternion = checked_tcp(tool)
    mass, cog = _checked_load(tool)
    return (
        f"[TRUE,[[{fmt_list(position, MM_DECIMALS)}],"
        f"[{fmt_list(quaternion, QUATERNION_DECIMALS)}]],"
        f"[{fmt_number(mass, KG_DECIMALS)},[{fmt_list(cog, MM_DECIMALS)}],[1,0,0,0],0,0,0]]"
    )


def _checked_load(tool: ToolData) -> tuple[float, FloatArray]:
    mass = tool.mass_kg
    if mass is None or not np.isfinite(mass) or mass <= 0:
        # In words: the console's ABB card read "has None" (and "has nan" for a NaN).
        has = "none" if mass is None or not np.isfinite(mass) else f"{mass:g} kg"
        raise InvalidInput(
            "missing-load",
            f"an ABB tooldata needs the tool's mass (kg, > 0); tool {tool.name!r} has "
            f"{has}. ABB controllers refuse a held tool with mass 0: set the tool's "
            "load (mass_kg, cog_mm) first",
            loc=("load", "mass_kg"),
        )
    if tool.cog_mm is None:
        raise InvalidInput(
            "missing-load",
            f"an ABB tooldata needs the tool's centre of gravity (cog_mm, in the flange "
            f"frame); tool {tool.name!r} has none: set the tool's load.cog_mm",
            loc=("load", "cog_mm"),
        )
    cog = check_finite(tool.cog_mm, loc=("load", "cog_mm"))
    return float(mass), cog


def export_abb(tool: ToolData) -> ControllerExport:
    """``PERS tooldata <name>:=[TRUE,[[x,y,z],[q1..q4]],[mass,[cog],[1,0,0,0],0,0,0]];``."""
    position, quaternion = checked_tcp(tool)
    mass, cog = _checked_load(tool)
    name = rapid_name(tool)
    text = f"PERS tooldata {name}:={tooldata_value(tool)};"
    values: dict[str, object] = {
        "name": name,
        "robhold": True,
        "x": rounded(position[0], MM_DECIMALS),
        "y": rounded(position[1], MM_DECIMALS),
        "z": rounded(position[2], MM_DECIMALS),
        "q1": rounded(quaternion[0], QUATERNION_DECIMALS),
        "q2": rounded(quaternion[1], QUATERNION_DECIMALS),
        "q3": rounded(quaternion[2], QUATERNION_DECIMALS),
        "q4": rounded(quaternion[3], QUATERNION_DECIMALS),
        "mass_kg": rounded(mass, KG_DECIMALS),
        "cog_mm": [rounded(c, MM_DECIMALS) for c in cog],
    }
    if tool.slot is not None:
        values["slot"] = tool.slot
    return ControllerExport(format=FORMAT, text=text, values=values)


def parse_abb(text: str) -> tuple[FloatArray, FloatArray]:
    """A RAPID ``tooldata`` declaration -> (position (3,) mm, quaternion wxyz (4,))."""
    match = _PATTERN.search(text)
    if match is None:
        raise parse_error(FORMAT, "tooldata name:=[TRUE,[[x,y,z],[q1,q2,q3,q4]],...]", text)
    numbers = [float(g) for g in match.groups()[2:]]
    position: FloatArray = np.array(numbers[:3])
    quaternion = normalised_quaternions(np.array([numbers[3:]]), loc=("text",))[0]
    return position, quaternion
