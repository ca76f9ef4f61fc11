"""KRL structure values as the KRC prints them and as KUKAVARPROXY writes them.

The KRC's ShowVar prints a structure as ``{FRAME: X 0.0,Y 0.0,Z 150.0,A 0.0,B 0.0,C 0.0}``:
braces, an optional type name and colon, then ``NAME value`` members separated by commas,
with nested structures (``CM {FRAME: X 0.0,...}``) and arbitrary spaces. Some KRC versions
and proxies leave the type name out (``{X 0.0, Y 0.0, ...}``). KUKA System Software 8,
Programming manual for system integrators, "Data types: STRUC" and "Aggregates".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Union

from app.controllers.scanner import Scanner

KrlValue = Union[float, str, "KrlStruct"]
KrlStruct = dict[str, KrlValue]


class KrlSyntaxError(ValueError):
    """The text is not a KRL structure value."""


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


def format_struct(members: Mapping[str, float | Mapping[str, float]]) -> str:
    """{"X": 1.0, "CM": {"X": 0.0}} -> ``{X 1.000000,CM {X 0.0}}`` (no type name: the
    variable's declaration gives it)."""
    parts = []
    for name, value in members.items():
        if isinstance(value, Mapping):
            parts.append(f"{name} {format_struct(value)}")
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
