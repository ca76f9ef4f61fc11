"""Tool frames written as X Y Z and three fixed-axis angles: Fanuc, Yaskawa, Techman.

All three store a tool as X, Y, Z (mm) and rotations about the fixed flange X, Y, Z axes
(deg), R = Rz(third) Ry(second) Rx(first):

- Fanuc UTOOL: X Y Z W P R (R-30iB/R-30iB Plus operator's manual, "Setting Up Coordinate
  Systems / Tool Frame, Direct Entry Method"). A TP program cannot assign literal numbers to
  a tool frame, so the text mirrors the Direct Entry screen, one field per value.
- Yaskawa tool file: X Y Z Rx Ry Rz, plus W (kg) and Xg Yg Zg (centre of gravity, mm)
  (YRC1000/DX200 operator's manual, "Tool Data Setting"); numbered 0..63.
- Techman: X Y Z RX RY RZ in TMflow's tool list, and TMscript ``ChangeTCP(float[])``
  with ``{X, Y, Z, RX, RY, RZ}`` (TM Expression Editor and Listen Node manual;
  ``ChangeTCP(float[], float)`` adds the mass).
"""

from __future__ import annotations

import re

import numpy as np

from app.exports.base import (
    DEG_DECIMALS,
    KG_DECIMALS,
    MM_DECIMALS,
    NUMBER,
    ControllerExport,
    FloatArray,
    ToolData,
    checked_tcp,
    comment_text,
    fmt_number,
    parse_error,
    rounded,
)
from app.kinematics.poses import (
    fanuc_wpr_from_matrix,
    matrix_from_fanuc_wpr,
    matrix_from_quaternion_wxyz,
    quaternion_wxyz_from_matrix,
)
from app.solvers.errors import SolveError

_DECIMALS = (MM_DECIMALS,) * 3 + (DEG_DECIMALS,) * 3
_LABELS: dict[str, tuple[str, ...]] = {
    "fanuc": ("X", "Y", "Z", "W", "P", "R"),
    "yaskawa": ("X", "Y", "Z", "Rx", "Ry", "Rz"),
    "techman": ("X", "Y", "Z", "RX", "RY", "RZ"),
}
_PREFIX = {"fanuc": "UTOOL", "yaskawa": "TOOL"}
_SLOTS = {"fanuc": (1, 10), "yaskawa": (0, 63)}


def _xyz_wpr(tool: ToolData) -> FloatArray:
    position, quaternion = checked_tcp(tool)
    wpr = fanuc_wpr_from_matrix(matrix_from_quaternion_wxyz(quaternion))
    numbers: FloatArray = np.concatenate([position, wpr])
    return numbers


def _check_slot(fmt: str, slot: int | None) -> None:
    low, high = _SLOTS[fmt]
    if slot is not None and not low <= slot <= high:
        raise SolveError(
            "invalid-options",
            f"a {fmt} tool number must be {low}..{high}, got {slot}",
            loc=("slot",),
        )


def _named_values(fmt: str, numbers: FloatArray) -> dict[str, object]:
    return {
        label: rounded(v, d) for label, v, d in zip(_LABELS[fmt], numbers, _DECIMALS, strict=True)
    }


def _fields_text(fmt: str, numbers: FloatArray) -> str:
    return " ".join(
        f"{label} {fmt_number(v, d)}"
        for label, v, d in zip(_LABELS[fmt], numbers, _DECIMALS, strict=True)
    )


def export_fanuc(tool: ToolData) -> ControllerExport:
    """``UTOOL[n]: X .. Y .. Z .. W .. P .. R ..`` (mm, deg), as on the Direct Entry screen."""
    _check_slot("fanuc", tool.slot)
    numbers = _xyz_wpr(tool)
    head = f"UTOOL[{tool.slot}]" if tool.slot is not None else "UTOOL"
    values: dict[str, object] = {"slot": tool.slot, **_named_values("fanuc", numbers)}
    text = f"{head}: {_fields_text('fanuc', numbers)}  ! {comment_text(tool.name)}"
    return ControllerExport(format="fanuc", text=text, values=values)


def export_yaskawa(tool: ToolData) -> ControllerExport:
    """``TOOL[n]: X Y Z Rx Ry Rz`` (mm, deg) and, with a load, ``W Xg Yg Zg`` (kg, mm)."""
    _check_slot("yaskawa", tool.slot)
    numbers = _xyz_wpr(tool)
    head = f"TOOL[{tool.slot}]" if tool.slot is not None else "TOOL"
    values: dict[str, object] = {"slot": tool.slot, **_named_values("yaskawa", numbers)}
    text = f"{head}: {_fields_text('yaskawa', numbers)}"
    if tool.mass_kg is not None:
        values["W"] = rounded(tool.mass_kg, KG_DECIMALS)
        text += f" W {fmt_number(tool.mass_kg, KG_DECIMALS)}"
        if tool.cog_mm is not None:
            for label, c in zip(("Xg", "Yg", "Zg"), tool.cog_mm, strict=True):
                values[label] = rounded(c, MM_DECIMALS)
                text += f" {label} {fmt_number(c, MM_DECIMALS)}"
    text = f"{text}  // {comment_text(tool.name)}"
    return ControllerExport(format="yaskawa", text=text, values=values)


def export_techman(tool: ToolData) -> ControllerExport:
    """TMscript ``ChangeTCP({X,Y,Z,RX,RY,RZ})`` (mm, deg), with the mass when known."""
    numbers = _xyz_wpr(tool)
    values: dict[str, object] = {"slot": tool.slot, **_named_values("techman", numbers)}
    pose = ",".join(fmt_number(v, d) for v, d in zip(numbers, _DECIMALS, strict=True))
    if tool.mass_kg is not None and tool.mass_kg > 0:
        values["mass_kg"] = rounded(tool.mass_kg, KG_DECIMALS)
        text = f"ChangeTCP({{{pose}}},{fmt_number(tool.mass_kg, KG_DECIMALS)})"
    else:
        text = f"ChangeTCP({{{pose}}})"
    text = f"{text}  // {comment_text(tool.name)}"
    return ControllerExport(format="techman", text=text, values=values)


def _tcp_from_numbers(numbers: list[float]) -> tuple[FloatArray, FloatArray]:
    position: FloatArray = np.array(numbers[:3])
    quaternion = quaternion_wxyz_from_matrix(matrix_from_fanuc_wpr(np.array(numbers[3:6])))
    return position, quaternion


def _parse_labelled(fmt: str, text: str) -> tuple[FloatArray, FloatArray]:
    labels = _LABELS[fmt]
    pattern = r"[\s:,]+".join(rf"{label}\s*[=:]?\s*({NUMBER})" for label in labels)
    match = re.search(rf"(?<![A-Za-z]){pattern}", text)
    if match is None:
        raise parse_error(fmt, " ".join(f"{label} <number>" for label in labels), text)
    return _tcp_from_numbers([float(g) for g in match.groups()])


def parse_fanuc(text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. W .. P .. R ..`` -> (position (3,) mm, quaternion wxyz (4,))."""
    return _parse_labelled("fanuc", text)


def parse_yaskawa(text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. Rx .. Ry .. Rz ..`` -> (position (3,) mm, quaternion wxyz (4,))."""
    return _parse_labelled("yaskawa", text)


def parse_techman(text: str) -> tuple[FloatArray, FloatArray]:
    """``ChangeTCP({X,Y,Z,RX,RY,RZ}...)`` -> (position (3,) mm, quaternion wxyz (4,))."""
    six = r"\s*,\s*".join([f"({NUMBER})"] * 6)
    match = re.search(rf"ChangeTCP\s*\(\s*\{{\s*{six}\s*\}}", text)
    if match is None:
        raise parse_error("techman", "ChangeTCP({X,Y,Z,RX,RY,RZ})", text)
    return _tcp_from_numbers([float(g) for g in match.groups()])
