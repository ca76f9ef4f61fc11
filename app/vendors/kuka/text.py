"""KUKA's text: KRL structure values, as the KRC prints them and KUKAVARPROXY writes them,
and a tool's ``$TOOL_DATA[n]={X ..,Y ..,Z ..,A ..,B ..,C ..}`` written with them.

The KRC's ShowVar prints a structure as ``{FRAME: X 0.0,Y 0.0,Z 150.0,A 0.0,B 0.0,C 0.0}``:
braces, an optional type name and colon, then ``NAME value`` members separated by commas,
with nested structures (``CM {FRAME: X 0.0,...}``) and arbitrary spaces. Some KRC versions
and proxies leave the type name out (``{X 0.0, Y 0.0, ...}``). KUKA System Software 8,
Programming manual for system integrators, "Data types: STRUC" and "Aggregates".

KSS tool frames are FRAME values in mm and degrees with R = Rz(A) Ry(B) Rx(C) (KUKA System
Software 8.x operating and programming manual, "FRAME"; the $TOOL_DATA[1..16] array in
$config.dat / R1/Mada/$machine.dat). A tool number (slot) is required: a KRL tool has no
name-only form. The tool's text (`export`, `parse`), the $config.dat lines of the file
(app.vendors.kuka.file) and what the connector reads and writes (app.vendors.kuka.kvp) are
all these structures: one grammar, read by `parse_struct`, written by `format_struct`. The
text prints the fewest digits that keep its precision (app.vendors.text: "Z 150.0"), the
connector six decimals (`format_real`, "Z 150.000000").
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Union

import numpy as np

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.kinematics.poses import (
    kuka_abc_from_matrix,
    matrix_from_kuka_abc,
    matrix_from_quaternion_wxyz,
    quaternion_wxyz_from_matrix,
)
from app.vendors.kuka import TOOL_NUMBERS
from app.vendors.scanner import Scanner
from app.vendors.text import (
    DEG_DECIMALS,
    MM_DECIMALS,
    ControllerExport,
    checked_tcp,
    fmt_number,
    parse_error,
    rounded,
)
from app.vendors.tool import ToolData

KrlValue = Union[float, str, "KrlStruct"]
KrlStruct = dict[str, KrlValue]
#: What `format_struct` writes: numbers, tokens written as they are, nested structures.
KrlMembers = Mapping[str, Union[float, str, "KrlMembers"]]

FORMAT = "kuka"
FIRST_SLOT, MAX_SLOT = TOOL_NUMBERS
FRAME_MEMBERS = ("X", "Y", "Z", "A", "B", "C")
_ASSIGNMENT = re.compile(
    r"(?<![A-Za-z0-9_])\$?TOOL_DATA\[\s*(\d+)\s*\]\s*=\s*(\{[^{}]*\})", re.IGNORECASE
)


class KrlSyntaxError(ValueError):
    """The text is not a KRL structure value."""


class KrlNotFinite(KrlSyntaxError):
    """A FRAME value holds a number that is not finite."""


def parse_struct(text: str) -> KrlStruct:
    """``{FRAME: X 1.0,Y 2.0,...}`` -> {"X": 1.0, "Y": 2.0, ...}; nested structures as dicts.

    Numbers become floats; enum values (``#NONE``), booleans and strings stay text.
    """
    parser = _Parser(text)
    value = parser.struct()
    parser.finish("structure")
    return value


def format_real(value: float) -> str:
    """A REAL as KRL reads it: plain decimal notation, six decimals, never an exponent."""
    if not math.isfinite(value):
        raise ValueError(f"{value} cannot be written to a KRL REAL")
    text = f"{value:.6f}"
    return "0.0" if text in ("-0.000000", "0.000000") else text


def format_struct(members: KrlMembers) -> str:
    """{"X": 1.0, "CM": {"X": 0.0}} -> ``{X 1.000000,CM {X 0.0}}`` (no type name: the
    variable's declaration gives it); a text member is written as it is ("150.0", "#NONE")."""
    parts = []
    for name, value in members.items():
        if isinstance(value, Mapping):
            parts.append(f"{name} {format_struct(value)}")
        elif isinstance(value, str):
            parts.append(f"{name} {value}")
        else:
            parts.append(f"{name} {format_real(value)}")
    return "{" + ",".join(parts) + "}"


def numbers(struct: KrlStruct, names: tuple[str, ...], *, what: str) -> tuple[float, ...]:
    """The members `names` of `struct` as floats; KrlSyntaxError naming a missing one."""
    values = []
    for name in names:
        value = struct.get(name)
        if not isinstance(value, float):
            raise KrlSyntaxError(f"{what} has no number {name}: {struct!r}")
        values.append(value)
    return tuple(values)


def krl_frame(position: FloatArray, quaternion: FloatArray) -> tuple[dict[str, float], str]:
    """({X..C rounded as printed}, ``{X ..,Y ..,Z ..,A ..,B ..,C ..}``) of a pose: mm and
    KUKA's A B C (deg), the fewest digits that keep the text's precision."""
    abc = kuka_abc_from_matrix(matrix_from_quaternion_wxyz(quaternion))
    decimals = (MM_DECIMALS,) * 3 + (DEG_DECIMALS,) * 3
    members = list(zip(FRAME_MEMBERS, np.concatenate([position, abc]), decimals, strict=True))
    values = {name: rounded(v, d) for name, v, d in members}
    return values, format_struct({name: fmt_number(v, d) for name, v, d in members})


def pose_of_frame(value: str) -> tuple[FloatArray, FloatArray]:
    """A FRAME value ``{X,Y,Z,A,B,C}`` -> (position (3,) mm, quaternion wxyz (4,));
    KrlSyntaxError when it is not one of finite numbers."""
    frame = np.array(numbers(parse_struct(value), FRAME_MEMBERS, what="the frame"))
    if not np.isfinite(frame).all():
        raise KrlNotFinite(f"the frame holds a number that is not finite: {value!r}")
    position: FloatArray = frame[:3]
    return position, quaternion_wxyz_from_matrix(matrix_from_kuka_abc(frame[3:]))


def export(tool: ToolData) -> ControllerExport:
    """``$TOOL_DATA[slot]={X,Y,Z (mm),A,B,C (deg)}``; InvalidInput if the slot is missing."""
    if tool.slot is None or not FIRST_SLOT <= tool.slot <= MAX_SLOT:
        # Said in words: "got None" reached the console's KUKA card and the API's 422.
        has = "it has none" if tool.slot is None else f"its slot {tool.slot} is not one"
        raise InvalidInput(
            "invalid-options",
            f"a KUKA tool needs its tool number (slot {FIRST_SLOT}..{MAX_SLOT}) for $TOOL_DATA[n]; "
            f"{has}: set the tool's slot",
            loc=("slot",),
        )
    position, quaternion = checked_tcp(tool)
    members, frame = krl_frame(position, quaternion)
    values: dict[str, object] = {"slot": tool.slot, **members}
    return ControllerExport(format=FORMAT, text=f"$TOOL_DATA[{tool.slot}]={frame}", values=values)


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """KRL ``$TOOL_DATA[n]={X,Y,Z,A,B,C}`` (or $config.dat's ``TOOL_DATA[n]=...``) ->
    (position (3,) mm, quaternion wxyz (4,))."""
    match = _ASSIGNMENT.search(text)
    try:
        if match is None:
            raise KrlSyntaxError("no $TOOL_DATA[n]= assignment")
        return pose_of_frame(match.group(2))
    except KrlNotFinite as err:
        raise parse_error(FORMAT, "finite numbers in $TOOL_DATA[n]={X x,...,C c}", text) from err
    except KrlSyntaxError as err:
        raise parse_error(FORMAT, "$TOOL_DATA[n]={X x,Y y,Z z,A a,B b,C c}", text) from err


class _Parser(Scanner):
    error = KrlSyntaxError

    def name(self) -> str:
        self.skip_spaces()
        start = self.pos
        while self.pos < len(self.text) and (
            self.text[self.pos].isalnum() or self.text[self.pos] in "_$"
        ):
            self.pos += 1
        if start == self.pos:
            raise KrlSyntaxError(f"expected a name at {start} of {self.text!r}")
        return self.text[start : self.pos]

    def struct(self) -> KrlStruct:
        self.expect("{")
        members: KrlStruct = {}
        if self.peek() == "}":
            self.pos += 1
            return members
        first = self.name()
        if self.peek() == ":":  # the type name, e.g. FRAME:
            self.pos += 1
            if self.peek() == "}":
                self.pos += 1
                return members
            first = self.name()
        members[first] = self.value()
        while self.peek() == ",":
            self.pos += 1
            key = self.name()
            members[key] = self.value()
        self.expect("}")
        return members

    def value(self) -> KrlValue:
        if self.peek() == "{":
            return self.struct()
        start, token = self.token(",}")
        if not token:
            raise KrlSyntaxError(f"a member without a value at {start} of {self.text!r}")
        try:
            return float(token)
        except ValueError:
            return token
