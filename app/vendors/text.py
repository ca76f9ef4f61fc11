"""What every maker's text shares: the result, the checked TCP, number printing and reading.

Printed precision: the text goes to a controller whose REAL is a 32-bit float (KRL REAL,
RAPID num: about 7 significant digits), so more digits than that change nothing on the robot.
We still print enough that parsing the text gives the TCP back within 1e-6 mm and 1e-6 deg
(our round-trip test), so a pasted text never silently loses calibration accuracy:

- mm: 6 decimals, rounding <= 5e-7 mm per axis (<= 8.7e-7 mm in 3D);
- deg: 7 decimals, <= 5e-8 deg per angle (<= 1.5e-7 deg for three Euler angles);
- quaternion components: 9 decimals (<= 1e-7 deg);
- m and rad (format `ur`): 10 decimals (<= 8.7e-8 mm, <= 1e-8 deg).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.jsontypes import JsonObject
from app.solvers.validation import check_positions_mm, normalised_quaternions
from app.vendors.tool import Posed

MM_DECIMALS = 6
DEG_DECIMALS = 7
QUATERNION_DECIMALS = 9
SI_DECIMALS = 10
#: Masses, kg: a gram is finer than any tool's load is known.
KG_DECIMALS = 3


@dataclass(frozen=True)
class ControllerExport:
    """A TCP in one controller's text, and the same numbers by name (plain JSON values)."""

    format: str
    text: str
    values: JsonObject


def checked_tcp(tool: Posed) -> tuple[FloatArray, FloatArray]:
    """The tool's (or frame's) (position (3,) mm, unit quaternion wxyz (4,)), checked like
    any pose."""
    try:
        position = check_positions_mm(np.asarray([tool.position_mm]), loc=("tcp",))[0]
    except InvalidInput as err:
        raise InvalidInput(err.kind, err.detail, loc=("tcp", "position_mm")) from err
    try:
        quaternion = normalised_quaternions(np.asarray([tool.quaternion]), loc=("tcp",))[0]
    except InvalidInput as err:
        raise InvalidInput(err.kind, err.detail, loc=("tcp", "quaternion")) from err
    return position, quaternion


def comment_text(name: str, limit: int = 40) -> str:
    """`name` safe inside a one-line controller comment: printable, no line breaks, short.

    A tool name is user input; a newline in it would otherwise start a new program line.
    """
    cleaned = "".join(ch if ch.isprintable() else " " for ch in name)
    return " ".join(cleaned.split())[:limit]


def rounded(value: float, decimals: int) -> float:
    """`value` rounded to `decimals`, with -0.0 turned into 0.0 (controllers print "-0")."""
    r = round(float(value), decimals)
    return 0.0 if r == 0 else r


def fmt_number(value: float, decimals: int) -> str:
    """`value` to `decimals` places, trailing zeros dropped ("150.0", not "150.000000").

    Short text is what a technician reads on the pendant ($TOOL_DATA[3]={X 0.0,Y 0.0,Z 150.0,
    A 0.0,B 0.0,C 0.0}); the rounding, and so the round-trip precision, is the same either
    way. No negative zero.
    """
    text = f"{rounded(value, decimals):.{decimals}f}".rstrip("0")
    return text + "0" if text.endswith(".") else text


def fmt_list(values: Sequence[float] | ArrayLike, decimals: int, sep: str = ",") -> str:
    """Comma-separated fixed-point numbers."""
    return sep.join(fmt_number(v, decimals) for v in np.asarray(values, dtype=np.float64))


NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_error(fmt: str, expected: str, text: str) -> InvalidInput:
    """The error for text that is not what `fmt` looks like."""
    shown = text if len(text) <= 120 else text[:117] + "..."
    return InvalidInput(
        "invalid-pose",
        f"cannot read {fmt} tool data: expected {expected}, got {shown!r}",
        loc=("text",),
    )
