"""ABB's text: RAPID ``tooldata`` and ``wobjdata`` values, read and written once, for the
tool's line ``PERS tooldata name:=[TRUE,[[x,y,z],[q1,q2,q3,q4]],[load]];``, the RAPID module
of the file (app.vendors.abb.file) and what Robot Web Services reads and writes
(app.vendors.abb.rws).

ABB *Technical reference manual - RAPID Instructions, Functions and Data types*,
"tooldata": ``[robhold, tframe, tload]`` with tframe a ``pose`` ``[[x, y, z], [q1, q2, q3,
q4]]`` (mm; q1 the scalar part) and tload a ``loaddata`` ``[mass, [cog x, y, z], [aom q1 ..
q4], ix, iy, iz]`` (kg, mm, kg m2). Aggregates are bracketed, comma separated; booleans
TRUE/FALSE; num literals may carry an exponent (``9E+09``). The manual's example: ``PERS
tooldata gripper := [TRUE, [[97.4, 0, 223.1], [0.924, 0, 0.383, 0]], [5, [23, 0, 75], [1, 0,
0, 0], 0, 0, 0]];``.

A held tool with mass 0 is refused by the controller when the tool is used in a move, so the
text refuses it too, with the reason, rather than hand out text that stops the robot later.
The text's inertia is 0 (a point load), which RAPID accepts. The text prints numbers as a
person reads them (app.vendors.text.fmt_number: "150.0", the mass to the gram); RWS takes them
as RAPID prints them (`rapid_num`: "150", six decimals); `format_tooldata` writes both.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Protocol, TypeAlias

import numpy as np

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.validation import check_finite, normalised_quaternions
from app.vendors.names import identifier
from app.vendors.scanner import Scanner
from app.vendors.text import (
    KG_DECIMALS,
    MM_DECIMALS,
    QUATERNION_DECIMALS,
    ControllerExport,
    checked_tcp,
    fmt_number,
    parse_error,
    rounded,
)
from app.vendors.tool import ToolData, vec3, vec4

RapidValue: TypeAlias = float | bool | str | list["RapidValue"]

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

#: Where a tooldata's value starts: after ``tooldata <name> :=``, at its "[".
_DECLARED = re.compile(r"tooldata\s+([A-Za-z][A-Za-z0-9_]*)\s*:=\s*(?=\[)", re.IGNORECASE)


class RapidSyntaxError(ValueError):
    """The text is not the RAPID value it should be."""


@dataclass(frozen=True)
class RapidTool:
    """A RAPID tooldata, every member kept (what tcpcal writes, and what it keeps)."""

    robhold: bool
    position_mm: tuple[float, float, float]
    quaternion: tuple[float, float, float, float]  # q1 (scalar), q2, q3, q4
    mass_kg: float
    cog_mm: tuple[float, float, float]
    aom: tuple[float, float, float, float]
    inertia: tuple[float, float, float]


def parse_value(text: str) -> RapidValue:
    """RAPID value text -> nested lists of floats, bools and other tokens (as text)."""
    parser = _Parser(text)
    value = parser.value()
    parser.finish("value")
    return value


def parse_tooldata(text: str) -> RapidTool:
    """``[TRUE,[[0,0,150],[1,0,0,0]],[2.5,[0,0,80],[1,0,0,0],0,0,0]]`` -> RapidTool."""
    return tooldata_of(parse_value(text), text)


def value_at(text: str, start: int) -> RapidValue:
    """The RAPID value that starts at ``text[start]``, whatever follows it."""
    return _Parser(text, start).value()


def tooldata_at(text: str, start: int) -> RapidTool:
    """The tooldata aggregate that starts at ``text[start]`` (a "["), whatever follows it."""
    return tooldata_of(value_at(text, start), text)


def tooldata_of(value: RapidValue, text: str) -> RapidTool:
    """A parsed RAPID value -> RapidTool; RapidSyntaxError naming the member that is not one."""
    if not isinstance(value, list) or len(value) != 3:
        raise RapidSyntaxError(f"not a tooldata [robhold, tframe, tload]: {text!r}")
    robhold, tframe, tload = value
    if not isinstance(robhold, bool):
        raise RapidSyntaxError(f"tooldata robhold is not TRUE or FALSE: {text!r}")
    if not isinstance(tframe, list) or len(tframe) != 2:
        raise RapidSyntaxError(f"tooldata tframe is not a pose [trans, rot]: {text!r}")
    if not isinstance(tload, list) or len(tload) != 6:
        raise RapidSyntaxError(f"tooldata tload is not a loaddata of 6 members: {text!r}")
    trans = _numbers(tframe[0], 3, "tframe.trans", text)
    rot = _numbers(tframe[1], 4, "tframe.rot", text)
    mass = _numbers([tload[0]], 1, "tload.mass", text)[0]
    cog = _numbers(tload[1], 3, "tload.cog", text)
    aom = _numbers(tload[2], 4, "tload.aom", text)
    inertia = _numbers(tload[3:], 3, "tload.ix/iy/iz", text)
    return RapidTool(
        robhold=robhold,
        position_mm=(trans[0], trans[1], trans[2]),
        quaternion=(rot[0], rot[1], rot[2], rot[3]),
        mass_kg=mass,
        cog_mm=(cog[0], cog[1], cog[2]),
        aom=(aom[0], aom[1], aom[2], aom[3]),
        inertia=(inertia[0], inertia[1], inertia[2]),
    )


def format_tooldata(
    tool: RapidTool, *, number: Callable[[float, int], str] | None = None, mass_decimals: int = 6
) -> str:
    """RapidTool -> RAPID text: what RWS's ``value`` takes, or (`number` fmt_number, the mass
    to `mass_decimals`) the tool's text. Position, quaternion, mass and centre of gravity are
    printed by `number` (`rapid_num` unless given); aom and inertia always by `rapid_num`."""
    put = number or rapid_num

    def listed(values: Iterable[float], decimals: int) -> str:
        return "[" + ",".join(put(v, decimals) for v in values) + "]"

    return (
        f"[{'TRUE' if tool.robhold else 'FALSE'},"
        f"[{listed(tool.position_mm, 6)},{listed(tool.quaternion, 9)}],"
        f"[{put(tool.mass_kg, mass_decimals)},{listed(tool.cog_mm, 6)},{_list(tool.aom, 9)},"
        f"{','.join(rapid_num(v, 9) for v in tool.inertia)}]]"
    )


@dataclass(frozen=True)
class RapidWobj:
    """A RAPID wobjdata (the same manual, "wobjdata": ``[robhold, ufprog, ufmec, uframe,
    oframe]``), every member kept: robhold TRUE when the robot holds the work object, ufprog
    TRUE for a fixed user frame, ufmec the mechanical unit moving it (a string literal, kept
    as printed), uframe the user frame in the world and oframe the object frame in it."""

    robhold: bool
    ufprog: bool
    ufmec: str
    uframe: tuple[tuple[float, float, float], tuple[float, float, float, float]]
    oframe: tuple[tuple[float, float, float], tuple[float, float, float, float]]


def parse_wobjdata(text: str) -> RapidWobj:
    """``[FALSE,TRUE,"",[[300,600,200],[1,0,0,0]],[[0,200,30],[1,0,0,0]]]`` (the manual's
    example) -> RapidWobj; RapidSyntaxError naming the member that is not one."""
    value = parse_value(text)
    if not isinstance(value, list) or len(value) != 5:
        raise RapidSyntaxError(f"not a wobjdata [robhold, ufprog, ufmec, uframe, oframe]: {text!r}")
    robhold, ufprog, ufmec, uframe, oframe = value
    if not isinstance(robhold, bool) or not isinstance(ufprog, bool):
        raise RapidSyntaxError(f"wobjdata robhold or ufprog is not TRUE or FALSE: {text!r}")
    if not isinstance(ufmec, str) or not (ufmec.startswith('"') and ufmec.endswith('"')):
        raise RapidSyntaxError(f"wobjdata ufmec is not a string: {text!r}")
    return RapidWobj(
        robhold, ufprog, ufmec, _pose(uframe, "uframe", text), _pose(oframe, "oframe", text)
    )


def _pose(
    value: RapidValue, what: str, text: str
) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    if not isinstance(value, list) or len(value) != 2:
        raise RapidSyntaxError(f"wobjdata {what} is not a pose [trans, rot]: {text!r}")
    trans = _numbers(value[0], 3, f"{what}.trans", text, data="wobjdata")
    rot = _numbers(value[1], 4, f"{what}.rot", text, data="wobjdata")
    return (trans[0], trans[1], trans[2]), (rot[0], rot[1], rot[2], rot[3])


def format_wobjdata(wobj: RapidWobj) -> str:
    """RapidWobj -> RAPID text, what RWS's ``value`` takes (numbers as `rapid_num`)."""

    def pose(frame: tuple[tuple[float, ...], tuple[float, ...]]) -> str:
        return f"[{_list(frame[0], 6)},{_list(frame[1], 9)}]"

    return (
        f"[{'TRUE' if wobj.robhold else 'FALSE'},{'TRUE' if wobj.ufprog else 'FALSE'},"
        f"{wobj.ufmec},{pose(wobj.uframe)},{pose(wobj.oframe)}]"
    )


def rapid_num(value: float, decimals: int) -> str:
    """A num as RAPID prints it: at most `decimals` places, no trailing zeros ("150", "0")."""
    if not math.isfinite(value):
        raise ValueError(f"{value} cannot be written to a RAPID num")
    text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def _list(values: tuple[float, ...], decimals: int) -> str:
    return "[" + ",".join(rapid_num(v, decimals) for v in values) + "]"


def _numbers(
    value: RapidValue, count: int, what: str, text: str, *, data: str = "tooldata"
) -> list[float]:
    if (
        not isinstance(value, list)
        or len(value) != count
        or not all(isinstance(v, float) and math.isfinite(v) for v in value)
    ):
        raise RapidSyntaxError(f"{data} {what} is not {count} finite numbers: {text!r}")
    return [float(v) for v in value if isinstance(v, float)]


class _Parser(Scanner):
    error = RapidSyntaxError

    def __init__(self, text: str, start: int = 0) -> None:
        super().__init__(text)
        self.pos = start

    def value(self) -> RapidValue:
        if self.peek() == "[":
            return self.aggregate()
        start, token = self.token(",]")
        if not token:
            raise RapidSyntaxError(f"a missing value at {start} of {self.text!r}")
        if token.upper() in ("TRUE", "FALSE"):
            return token.upper() == "TRUE"
        try:
            return float(token)
        except ValueError:
            return token

    def aggregate(self) -> list[RapidValue]:
        self.pos += 1  # "["
        items = [self.value()]
        while self.peek() == ",":
            self.pos += 1
            items.append(self.value())
        if self.peek() != "]":
            raise RapidSyntaxError(f"an aggregate not closed by ] at {self.pos} of {self.text!r}")
        self.pos += 1
        return items


def rapid_identifier(name: str) -> str:
    """`name` made a valid RAPID data name: [A-Za-z][A-Za-z0-9_]*, <= 32 chars, not reserved
    (accents taken off, other characters an underscore, "t" in front of a leading digit)."""
    return identifier(name, MAX_IDENTIFIER, fallback="t", reserved=_RESERVED)


class Symbolled(Protocol):
    """What a RAPID data name is made from: a name and a controller symbol (a ToolData, a
    FrameData)."""

    @property
    def name(self) -> str: ...
    @property
    def controller_symbol(self) -> str | None: ...


def rapid_name(tool: Symbolled) -> str:
    """The data's name: SYMBOL of the controller_symbol "TASK/MODULE/SYMBOL" (the persistent
    the robot's programs move by), else the tool's (frame's) name made an identifier."""
    if tool.controller_symbol:
        return rapid_identifier(tool.controller_symbol.rsplit("/", 1)[-1])
    return rapid_identifier(tool.name)


def tooldata_value(tool: ToolData) -> str:
    """``[TRUE,[[x,y,z],[q1..q4]],[mass,[cog],[1,0,0,0],0,0,0]]``: the tool's tooldata value."""
    position, quaternion = checked_tcp(tool)
    mass, cog = _checked_load(tool)
    point_load = RapidTool(
        True, vec3(position), vec4(quaternion), mass, vec3(cog), (1, 0, 0, 0), (0, 0, 0)
    )
    return format_tooldata(point_load, number=fmt_number, mass_decimals=KG_DECIMALS)


def _checked_load(tool: ToolData) -> tuple[float, FloatArray]:
    load = tool.load
    if load is None or not np.isfinite(load.mass_kg) or load.mass_kg <= 0:
        # In words: the console's ABB card read "has None" (and "has nan" for a NaN).
        has = "none" if load is None or not np.isfinite(load.mass_kg) else f"{load.mass_kg:g} kg"
        raise InvalidInput(
            "missing-load",
            f"an ABB tooldata needs the tool's mass (kg, > 0); tool {tool.name!r} has "
            f"{has}. ABB controllers refuse a held tool with mass 0: set the tool's "
            "load (mass_kg, cog_mm) first",
            loc=("load", "mass_kg"),
        )
    if load.cog_mm is None:
        raise InvalidInput(
            "missing-load",
            f"an ABB tooldata needs the tool's centre of gravity (cog_mm, in the flange "
            f"frame); tool {tool.name!r} has none: set the tool's load.cog_mm",
            loc=("load", "cog_mm"),
        )
    cog = check_finite(np.asarray(load.cog_mm), loc=("load", "cog_mm"))
    return load.mass_kg, cog


def export(tool: ToolData) -> ControllerExport:
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


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """A RAPID ``tooldata`` declaration -> (position (3,) mm, quaternion wxyz (4,))."""
    match = _DECLARED.search(text)
    try:
        if match is None:
            raise RapidSyntaxError("no tooldata declaration")
        tool = tooldata_at(text, match.end())
    except RapidSyntaxError as err:
        raise parse_error(
            FORMAT, "tooldata name:=[TRUE,[[x,y,z],[q1,q2,q3,q4]],...]", text
        ) from err
    return np.array(tool.position_mm), unit_quaternion(tool.quaternion)


def unit_quaternion(quaternion: tuple[float, float, float, float]) -> FloatArray:
    """q1..q4 of a pasted tooldata, normalised (422 naming the text when it is no rotation)."""
    unit: FloatArray = normalised_quaternions(np.array([quaternion]), loc=("text",))[0]
    return unit
