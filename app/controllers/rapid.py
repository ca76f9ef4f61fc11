"""RAPID data values as text, as Robot Web Services reads and writes them: ``tooldata``.

ABB *Technical reference manual - RAPID Instructions, Functions and Data types*,
"tooldata": ``[robhold, tframe, tload]`` with tframe a ``pose`` ``[[x, y, z], [q1, q2, q3,
q4]]`` (mm; q1 the scalar part) and tload a ``loaddata`` ``[mass, [cog x, y, z], [aom q1 ..
q4], ix, iy, iz]`` (kg, mm, kg m2). Aggregates are bracketed, comma separated; booleans
TRUE/FALSE; num literals may carry an exponent (``9E+09``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeAlias

from app.controllers.scanner import Scanner

RapidValue: TypeAlias = float | bool | str | list["RapidValue"]


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
    value = parse_value(text)
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


def format_tooldata(tool: RapidTool) -> str:
    """RapidTool -> the RAPID text RWS's ``value`` takes."""
    return (
        f"[{'TRUE' if tool.robhold else 'FALSE'},"
        f"[{_list(tool.position_mm, 6)},{_list(tool.quaternion, 9)}],"
        f"[{_num(tool.mass_kg, 6)},{_list(tool.cog_mm, 6)},{_list(tool.aom, 9)},"
        f"{','.join(_num(v, 9) for v in tool.inertia)}]]"
    )


def _num(value: float, decimals: int) -> str:
    if not math.isfinite(value):
        raise ValueError(f"{value} cannot be written to a RAPID num")
    text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def _list(values: tuple[float, ...], decimals: int) -> str:
    return "[" + ",".join(_num(v, decimals) for v in values) + "]"


def _numbers(value: RapidValue, count: int, what: str, text: str) -> list[float]:
    if (
        not isinstance(value, list)
        or len(value) != count
        or not all(isinstance(v, float) and math.isfinite(v) for v in value)
    ):
        raise RapidSyntaxError(f"tooldata {what} is not {count} finite numbers: {text!r}")
    return [float(v) for v in value if isinstance(v, float)]


class _Parser(Scanner):
    error = RapidSyntaxError

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
