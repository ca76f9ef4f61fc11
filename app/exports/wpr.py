"""Tool frames written as X Y Z and three fixed-axis angles: Fanuc, Yaskawa, Techman.

All three store a tool as X, Y, Z (mm) and rotations about the fixed flange X, Y, Z axes
(deg), R = Rz(third) Ry(second) Rx(first) (the project's convention for all three).

What public evidence backs, and what it does not (checked against stored public sources;
no vendor manual was available as a primary source, so "verified" below means "confirmed by
independent public code or manual excerpts", not "checked on a controller"):

- Fanuc. VERIFIED: the six fields X Y Z W P R in that order, mm and deg, and the angle
  convention (RoboDK's Fanuc post, ros-industrial-attic/robodk_postprocessors
  Fanuc_R30iA.py ``setTool`` writes ``PR[n,1..6]`` from ``Pose_2_Fanuc``, and robodk.py
  ``pose_2_xyzrpw``: H = transl(x,y,z) rotz(R) roty(P) rotx(W)); that a TP program *can*
  load literal numbers into a tool frame, through a position register:
  ``PR[n,1]=x ; .. PR[n,6]=r ; UTOOL[t]=PR[n] ;`` (same file; third-party notes cite
  HandlingTool V9.40 sec. 7.20 for "UTOOL[i]=PR[j]"). NOT VERIFIED: our one-line
  ``UTOOL[t]: X .. W .. R ..`` text is our own layout, a transcription of the Direct Entry
  screen, not controller syntax; UTOOL numbers 1..10 (R-30iB default; the count is a
  system setting). The parser also reads the TP form.
- Yaskawa. VERIFIED: Rx Ry Rz are the same fixed-axis angles as Fanuc's W P R (robodk.py
  ``Pose_2_Motoman`` is ``pose_2_xyzrpw``); the tool file holds X Y Z (mm), Rx Ry Rz (deg),
  the load W (kg) and its centre of gravity Xg Yg Zg (mm, flange frame) (Yaskawa manual text
  "Tool Load Information ... registered in the tool file", mirrored at
  https://stockdcs.com/Product/2630.html). INFORM sets a tool with ``SETTOOL TL#(n) P...``
  whose P variable holds 0.001 mm / 0.01 deg integers (RoboDK Motoman.py ``setTool``).
  NOT VERIFIED: our ``TOOL[n]: X .. Rz .. W .. Xg ..`` line (the JSON ``controller.text``) is
  our own layout, neither TOOL.CND nor INFORM (the file is app.exports.cnd_file's TOOL.CND);
  tool numbers 0..63 (YRC1000/DX200; NX100 had 0..23, per its job data
  format manual "///TOOL <N>: Tool No.(0 to 23)").
- Techman. VERIFIED: ``ChangeTCP`` takes X, Y, Z, RX, RY, RZ (mm, deg) then the mass (kg):
  the Expression Editor manual's syntaxes (as summarised by third-party notes, manual
  pp. 267-270) ``ChangeTCP(float[])``, ``ChangeTCP(float[], float)``,
  ``ChangeTCP(float[], float, float[])`` and the flat ``ChangeTCP(float x6[, float])``; the
  flat form is what a fork of TM's ROS driver writes (RAMLABNL/tmr_ros2
  tm_driver/src/tm_command.cpp
  ``TmCommand::change_tcp``, angles through ``deg()``) and techmanpy's ``set_tcp``
  (jvdtoorn/techmanpy techmanpy/clients/tmsct_client.py). TMscript array literals use
  braces (``float[] var_f = {1, 2, 3, 4}``), so our ``ChangeTCP({..},m)`` is the
  ``(float[], float)`` syntax. The parser reads both forms. NOT VERIFIED: that RX RY RZ
  compose as Rz Ry Rx (no public source found either way).
"""

from __future__ import annotations

import re

import numpy as np

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.exports.base import (
    DEG_DECIMALS,
    KG_DECIMALS,
    MM_DECIMALS,
    NUMBER,
    ControllerExport,
    ToolData,
    checked_tcp,
    comment_text,
    fmt_number,
    parse_error,
    rounded,
)
from app.exports.names import ascii_text
from app.kinematics.poses import (
    fanuc_wpr_from_matrix,
    matrix_from_fanuc_wpr,
    matrix_from_quaternion_wxyz,
    quaternion_wxyz_from_matrix,
)
from app.tool_numbers import TOOL_NUMBERS

_DECIMALS = (MM_DECIMALS,) * 3 + (DEG_DECIMALS,) * 3
_LABELS: dict[str, tuple[str, ...]] = {
    "fanuc": ("X", "Y", "Z", "W", "P", "R"),
    "yaskawa": ("X", "Y", "Z", "Rx", "Ry", "Rz"),
    "techman": ("X", "Y", "Z", "RX", "RY", "RZ"),
}
_PREFIX = {"fanuc": "UTOOL", "yaskawa": "TOOL"}


def xyz_wpr(tool: ToolData) -> FloatArray:
    position, quaternion = checked_tcp(tool)
    wpr = fanuc_wpr_from_matrix(matrix_from_quaternion_wxyz(quaternion))
    numbers: FloatArray = np.concatenate([position, wpr])
    return numbers


def check_slot(fmt: str, slot: int | None) -> None:
    low, high = TOOL_NUMBERS[fmt]
    if slot is not None and not low <= slot <= high:
        raise InvalidInput(
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
    check_slot("fanuc", tool.slot)
    numbers = xyz_wpr(tool)
    head = f"UTOOL[{tool.slot}]" if tool.slot is not None else "UTOOL"
    values: dict[str, object] = {"slot": tool.slot, **_named_values("fanuc", numbers)}
    text = f"{head}: {_fields_text('fanuc', numbers)}  ! {ascii_text(tool.name, 40, drop=';')}"
    return ControllerExport(format="fanuc", text=text, values=values)


def export_yaskawa(tool: ToolData) -> ControllerExport:
    """``TOOL[n]: X Y Z Rx Ry Rz`` (mm, deg) and, with a load, ``W Xg Yg Zg`` (kg, mm)."""
    check_slot("yaskawa", tool.slot)
    numbers = xyz_wpr(tool)
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
    text = f"{text}  // {ascii_text(tool.name, 40)}"
    return ControllerExport(format="yaskawa", text=text, values=values)


def export_techman(tool: ToolData) -> ControllerExport:
    """TMscript ``ChangeTCP({X,Y,Z,RX,RY,RZ})`` (mm, deg), with the mass when known."""
    numbers = xyz_wpr(tool)
    values: dict[str, object] = {"slot": tool.slot, **_named_values("techman", numbers)}
    pose = ",".join(fmt_number(v, d) for v, d in zip(numbers, _DECIMALS, strict=True))
    if tool.mass_kg is not None and tool.mass_kg > 0:
        values["mass_kg"] = rounded(tool.mass_kg, KG_DECIMALS)
        text = f"ChangeTCP({{{pose}}},{fmt_number(tool.mass_kg, KG_DECIMALS)})"
    else:
        text = f"ChangeTCP({{{pose}}})"
    text = f"{text}  // {comment_text(tool.name)}"
    return ControllerExport(format="techman", text=text, values=values)


def tcp_from_numbers(numbers: list[float]) -> tuple[FloatArray, FloatArray]:
    position: FloatArray = np.array(numbers[:3])
    quaternion = quaternion_wxyz_from_matrix(matrix_from_fanuc_wpr(np.array(numbers[3:6])))
    return position, quaternion


def _parse_labelled(fmt: str, text: str) -> tuple[FloatArray, FloatArray]:
    labels = _LABELS[fmt]
    pattern = r"[\s:,]+".join(rf"{label}\s*[=:]?\s*({NUMBER})" for label in labels)
    match = re.search(rf"(?<![A-Za-z]){pattern}", text)
    if match is None:
        raise parse_error(fmt, " ".join(f"{label} <number>" for label in labels), text)
    return tcp_from_numbers([float(g) for g in match.groups()])


# TP: a tool frame loaded from a position register whose six elements were set one by one,
# ``PR[n,1]=x ; .. PR[n,6]=r ; UTOOL[t]=PR[n] ;`` (ros-industrial-attic/robodk_postprocessors
# Fanuc_R30iA.py ``setTool``). A negative constant may be stored in parentheses, ``(-2.5)``.
_PR_ELEMENT = re.compile(rf"PR\[\s*(\d+)\s*,\s*([1-6])\s*\]\s*=\s*\(?\s*({NUMBER})\s*\)?")
_UTOOL_FROM_PR = re.compile(r"UTOOL\[\s*\d+\s*\]\s*=\s*PR\[\s*(\d+)\s*(?::[^\]]*)?\]")


def _parse_fanuc_tp(text: str) -> tuple[FloatArray, FloatArray] | None:
    assign = _UTOOL_FROM_PR.search(text)
    if assign is None:
        return None
    register = assign.group(1)
    elements: dict[int, float] = {}
    for match in _PR_ELEMENT.finditer(text[: assign.start()]):
        if match.group(1) == register:
            elements[int(match.group(2))] = float(match.group(3))
    if len(elements) < 6:
        return None
    return tcp_from_numbers([elements[i] for i in range(1, 7)])


def parse_fanuc(text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. W .. P .. R ..``, or TP ``PR[n,1..6]=.. ; UTOOL[t]=PR[n]`` ->
    (position (3,) mm, quaternion wxyz (4,))."""
    tp = _parse_fanuc_tp(text)
    return tp if tp is not None else _parse_labelled("fanuc", text)


def parse_yaskawa(text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. Rx .. Ry .. Rz ..`` -> (position (3,) mm, quaternion wxyz (4,))."""
    return _parse_labelled("yaskawa", text)


def parse_techman(text: str) -> tuple[FloatArray, FloatArray]:
    """``ChangeTCP({X,Y,Z,RX,RY,RZ}...)`` or the flat ``ChangeTCP(X,Y,Z,RX,RY,RZ...)`` (as
    TM's ROS driver writes it) -> (position (3,) mm, quaternion wxyz (4,))."""
    six = r"\s*,\s*".join([f"({NUMBER})"] * 6)
    # Braces around the six, or none; after them only ")" or "," (mass, inertia) may follow.
    match = re.search(rf"ChangeTCP\s*\(\s*(\{{)?\s*{six}\s*(?(1)\}})\s*[,)]", text)
    if match is None:
        raise parse_error("techman", "ChangeTCP({X,Y,Z,RX,RY,RZ})", text)
    return tcp_from_numbers([float(g) for g in match.groups()[1:]])
