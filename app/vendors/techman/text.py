"""Techman's text: TMscript ``ChangeTCP({X,Y,Z,RX,RY,RZ},mass)`` (mm, deg, kg), and its
reader. RX RY RZ are taken as the fixed-axis angles of app.vendors.wpr.

VERIFIED: ``ChangeTCP`` takes X, Y, Z, RX, RY, RZ (mm, deg) then the mass (kg):
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

from app.arrays import FloatArray
from app.vendors.text import (
    KG_DECIMALS,
    NUMBER,
    ControllerExport,
    comment_text,
    fmt_number,
    parse_error,
    rounded,
)
from app.vendors.tool import ToolData
from app.vendors.wpr import DECIMALS, named_values, tcp_from_numbers, xyz_wpr

FORMAT = "techman"
LABELS = ("X", "Y", "Z", "RX", "RY", "RZ")


def export(tool: ToolData) -> ControllerExport:
    """TMscript ``ChangeTCP({X,Y,Z,RX,RY,RZ})`` (mm, deg), with the mass when known."""
    numbers = xyz_wpr(tool)
    values: dict[str, object] = {"slot": tool.slot, **named_values(LABELS, numbers)}
    pose = ",".join(fmt_number(v, d) for v, d in zip(numbers, DECIMALS, strict=True))
    if tool.load is not None and tool.load.mass_kg > 0:
        values["mass_kg"] = rounded(tool.load.mass_kg, KG_DECIMALS)
        text = f"ChangeTCP({{{pose}}},{fmt_number(tool.load.mass_kg, KG_DECIMALS)})"
    else:
        text = f"ChangeTCP({{{pose}}})"
    text = f"{text}  // {comment_text(tool.name)}"
    return ControllerExport(format=FORMAT, text=text, values=values)


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """``ChangeTCP({X,Y,Z,RX,RY,RZ}...)`` or the flat ``ChangeTCP(X,Y,Z,RX,RY,RZ...)`` (as
    TM's ROS driver writes it) -> (position (3,) mm, quaternion wxyz (4,))."""
    six = r"\s*,\s*".join([f"({NUMBER})"] * 6)
    # Braces around the six, or none; after them only ")" or "," (mass, inertia) may follow.
    match = re.search(rf"ChangeTCP\s*\(\s*(\{{)?\s*{six}\s*(?(1)\}})\s*[,)]", text)
    if match is None:
        raise parse_error(FORMAT, "ChangeTCP({X,Y,Z,RX,RY,RZ})", text)
    return tcp_from_numbers([float(g) for g in match.groups()[1:]])
