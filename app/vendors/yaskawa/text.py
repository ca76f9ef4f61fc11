"""Yaskawa's text: ``TOOL[n]: X Y Z Rx Ry Rz`` (mm, deg) and, with a load, ``W Xg Yg Zg``
(kg, mm), and its reader. Rx Ry Rz are the fixed-axis angles of app.vendors.wpr.

VERIFIED: Rx Ry Rz are the same fixed-axis angles as `fanuc_wpr` (robodk.py
``Pose_2_Motoman`` is ``pose_2_xyzrpw``); the tool file holds X Y Z (mm), Rx Ry Rz (deg),
the load W (kg) and its centre of gravity Xg Yg Zg (mm, flange frame) (Yaskawa manual text
"Tool Load Information ... registered in the tool file", mirrored at
https://stockdcs.com/Product/2630.html). INFORM sets a tool with ``SETTOOL TL#(n) P...``
whose P variable holds 0.001 mm / 0.01 deg integers (RoboDK Motoman.py ``setTool``).
NOT VERIFIED: our ``TOOL[n]: X .. Rz .. W .. Xg ..`` line (the JSON ``controller.text``) is
our own layout, neither TOOL.CND nor INFORM (the file is app.vendors.yaskawa.file's TOOL.CND);
tool numbers 0..63 (YRC1000/DX200; NX100 had 0..23, per its job data
format manual "///TOOL <N>: Tool No.(0 to 23)").
"""

from __future__ import annotations

from app.arrays import FloatArray
from app.vendors.names import ascii_text
from app.vendors.text import KG_DECIMALS, MM_DECIMALS, ControllerExport, fmt_number, rounded
from app.vendors.tool import ToolData
from app.vendors.wpr import numbered_line, parse_labelled
from app.vendors.yaskawa import TOOL_NUMBERS

FORMAT = "yaskawa"
LABELS = ("X", "Y", "Z", "Rx", "Ry", "Rz")


def export(tool: ToolData) -> ControllerExport:
    """``TOOL[n]: X Y Z Rx Ry Rz`` (mm, deg) and, with a load, ``W Xg Yg Zg`` (kg, mm)."""
    text, values = numbered_line(FORMAT, "TOOL", LABELS, tool, TOOL_NUMBERS)
    if tool.load is not None:
        values["W"] = rounded(tool.load.mass_kg, KG_DECIMALS)
        text += f" W {fmt_number(tool.load.mass_kg, KG_DECIMALS)}"
        if tool.load.cog_mm is not None:
            for label, c in zip(("Xg", "Yg", "Zg"), tool.load.cog_mm, strict=True):
                values[label] = rounded(c, MM_DECIMALS)
                text += f" {label} {fmt_number(c, MM_DECIMALS)}"
    text = f"{text}  // {ascii_text(tool.name, 40)}"
    return ControllerExport(format=FORMAT, text=text, values=values)


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. Rx .. Ry .. Rz ..`` -> (position (3,) mm, quaternion wxyz (4,))."""
    return parse_labelled(FORMAT, LABELS, text)
