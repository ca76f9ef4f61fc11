"""Tool frames written as X Y Z and three fixed-axis angles (fanuc_wpr, yaskawa_rxyz,
techman_rxyz: the makers whose packages import this module).

All three store a tool as X, Y, Z (mm) and rotations about the fixed flange X, Y, Z axes
(deg), R = Rz(third) Ry(second) Rx(first) (the project's convention for all three; fanuc_wpr's
W P R). What public evidence backs it, and what it does not, is in each maker's text module
(app.vendors.fanuc.text, app.vendors.yaskawa.text, app.vendors.techman.text): no vendor manual
was available as a primary source, so "verified" there means "confirmed by independent public
code or manual excerpts", not "checked on a controller".
"""

from __future__ import annotations

import re

import numpy as np

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.kinematics.poses import (
    fanuc_wpr_from_matrix,
    matrix_from_fanuc_wpr,
    matrix_from_quaternion_wxyz,
    quaternion_wxyz_from_matrix,
)
from app.vendors.text import (
    DEG_DECIMALS,
    MM_DECIMALS,
    NUMBER,
    checked_tcp,
    fmt_number,
    parse_error,
    rounded,
)
from app.vendors.tool import Posed, ToolData

#: Printed places of X, Y, Z (mm) and the three angles (deg).
DECIMALS = (MM_DECIMALS,) * 3 + (DEG_DECIMALS,) * 3


def xyz_wpr(tool: Posed) -> FloatArray:
    """The tool's (or frame's) X, Y, Z (mm) and the three fixed-axis angles (deg), checked
    like any pose."""
    position, quaternion = checked_tcp(tool)
    wpr = fanuc_wpr_from_matrix(matrix_from_quaternion_wxyz(quaternion))
    numbers: FloatArray = np.concatenate([position, wpr])
    return numbers


def tcp_from_numbers(numbers: list[float]) -> tuple[FloatArray, FloatArray]:
    """X, Y, Z (mm) and the three angles (deg) -> (position (3,) mm, quaternion wxyz (4,))."""
    position: FloatArray = np.array(numbers[:3])
    quaternion = quaternion_wxyz_from_matrix(matrix_from_fanuc_wpr(np.array(numbers[3:6])))
    return position, quaternion


def check_slot(fmt: str, slot: int | None, numbers: tuple[int, int]) -> None:
    """422 at "slot" when a tool number is given outside the maker's `numbers`."""
    low, high = numbers
    if slot is not None and not low <= slot <= high:
        raise InvalidInput(
            "invalid-options",
            f"a {fmt} tool number must be {low}..{high}, got {slot}",
            loc=("slot",),
        )


def named_values(labels: tuple[str, ...], numbers: FloatArray) -> dict[str, object]:
    """{label: rounded number} of the six, as the JSON ``values`` name them."""
    return {label: rounded(v, d) for label, v, d in zip(labels, numbers, DECIMALS, strict=True)}


def fields_text(labels: tuple[str, ...], numbers: FloatArray) -> str:
    """``X .. Y .. Z .. W .. P .. R ..`` with the maker's labels."""
    return " ".join(
        f"{label} {fmt_number(v, d)}" for label, v, d in zip(labels, numbers, DECIMALS, strict=True)
    )


def numbered_line(
    fmt: str, prefix: str, labels: tuple[str, ...], tool: ToolData, numbers: tuple[int, int]
) -> tuple[str, dict[str, object]]:
    """(``PREFIX[n]: X .. Y .. Z .. <a> .. <b> .. <c> ..``, the JSON ``values``) of a tool
    whose number, when it has one, is within the maker's `numbers` (else 422 at "slot")."""
    check_slot(fmt, tool.slot, numbers)
    six = xyz_wpr(tool)
    head = f"{prefix}[{tool.slot}]" if tool.slot is not None else prefix
    values: dict[str, object] = {"slot": tool.slot, **named_values(labels, six)}
    return f"{head}: {fields_text(labels, six)}", values


def parse_labelled(fmt: str, labels: tuple[str, ...], text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. <a> .. <b> .. <c> ..`` (labels as given) -> (position, quaternion)."""
    pattern = r"[\s:,]+".join(rf"{label}\s*[=:]?\s*({NUMBER})" for label in labels)
    match = re.search(rf"(?<![A-Za-z]){pattern}", text)
    if match is None:
        raise parse_error(fmt, " ".join(f"{label} <number>" for label in labels), text)
    return tcp_from_numbers([float(g) for g in match.groups()])
