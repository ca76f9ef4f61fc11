"""KUKA KRL tool data: ``$TOOL_DATA[n]={X ..,Y ..,Z ..,A ..,B ..,C ..}``.

KSS tool frames are FRAME values in mm and degrees with R = Rz(A) Ry(B) Rx(C) (KUKA System
Software 8.x operating and programming manual, "FRAME"; the $TOOL_DATA[1..16] array in
$config.dat / R1/Mada/$machine.dat). A tool number (slot) is required: a KRL tool has no
name-only form.
"""

from __future__ import annotations

import re

import numpy as np

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.exports.base import (
    DEG_DECIMALS,
    MM_DECIMALS,
    NUMBER,
    ControllerExport,
    ToolData,
    checked_tcp,
    fmt_number,
    parse_error,
    rounded,
)
from app.kinematics.poses import (
    kuka_abc_from_matrix,
    matrix_from_kuka_abc,
    matrix_from_quaternion_wxyz,
    quaternion_wxyz_from_matrix,
)
from app.tool_numbers import TOOL_NUMBERS

FORMAT = "kuka"
FIRST_SLOT, MAX_SLOT = TOOL_NUMBERS[FORMAT]
_FIELDS = ("X", "Y", "Z", "A", "B", "C")
_PATTERN = re.compile(
    r"(?<![A-Za-z0-9_])\$?TOOL_DATA\[\s*(\d+)\s*\]\s*=\s*\{\s*"
    + r"\s*,\s*".join(rf"{name}\s+({NUMBER})" for name in _FIELDS)
    + r"\s*\}",
    re.IGNORECASE,
)


def export_kuka(tool: ToolData) -> ControllerExport:
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
    abc = kuka_abc_from_matrix(matrix_from_quaternion_wxyz(quaternion))
    decimals = (MM_DECIMALS,) * 3 + (DEG_DECIMALS,) * 3
    numbers = np.concatenate([position, abc])
    body = ",".join(
        f"{name} {fmt_number(v, d)}" for name, v, d in zip(_FIELDS, numbers, decimals, strict=True)
    )
    values: dict[str, object] = {"slot": tool.slot}
    values.update(
        {name: rounded(v, d) for name, v, d in zip(_FIELDS, numbers, decimals, strict=True)}
    )
    return ControllerExport(
        format=FORMAT, text=f"$TOOL_DATA[{tool.slot}]={{{body}}}", values=values
    )


def parse_kuka(text: str) -> tuple[FloatArray, FloatArray]:
    """KRL ``$TOOL_DATA[n]={X,Y,Z,A,B,C}`` (or $config.dat's ``TOOL_DATA[n]=...``) ->
    (position (3,) mm, quaternion wxyz (4,))."""
    match = _PATTERN.search(text)
    if match is None:
        raise parse_error(FORMAT, "$TOOL_DATA[n]={X x,Y y,Z z,A a,B b,C c}", text)
    numbers = np.array([float(g) for g in match.groups()[1:]])
    position: FloatArray = numbers[:3]
    quaternion = quaternion_wxyz_from_matrix(matrix_from_kuka_abc(numbers[3:]))
    return position, quaternion
