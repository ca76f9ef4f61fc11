"""FANUC's text: ``UTOOL[n]: X .. Y .. Z .. W .. P .. R ..`` (mm, deg), as on the Direct
Entry screen, and its reader (which also reads a TP program's ``PR[n,1..6]=.. ;
UTOOL[t]=PR[n]``). W P R are the fixed-axis angles of app.vendors.wpr, R = Rz(R) Ry(P) Rx(W).

VERIFIED: the six fields X Y Z W P R in that order, mm and deg, and the angle
convention (RoboDK's Fanuc post, ros-industrial-attic/robodk_postprocessors
Fanuc_R30iA.py ``setTool`` writes ``PR[n,1..6]`` from ``Pose_2_Fanuc``, and robodk.py
``pose_2_xyzrpw``: H = transl(x,y,z) rotz(R) roty(P) rotx(W)); that a TP program *can*
load literal numbers into a tool frame, through a position register:
``PR[n,1]=x ; .. PR[n,6]=r ; UTOOL[t]=PR[n] ;`` (same file; third-party notes cite
HandlingTool V9.40 sec. 7.20 for "UTOOL[i]=PR[j]"). NOT VERIFIED: our one-line
``UTOOL[t]: X .. W .. R ..`` text is our own layout, a transcription of the Direct Entry
screen, not controller syntax; UTOOL numbers 1..10 (R-30iB default; the count is a
system setting). The parser also reads the TP form.
"""

from __future__ import annotations

import re

from app.arrays import FloatArray
from app.vendors.fanuc import TOOL_NUMBERS
from app.vendors.names import ascii_text
from app.vendors.text import NUMBER, ControllerExport
from app.vendors.tool import ToolData
from app.vendors.wpr import numbered_line, parse_labelled, tcp_from_numbers

FORMAT = "fanuc"
LABELS = ("X", "Y", "Z", "W", "P", "R")


def export(tool: ToolData) -> ControllerExport:
    """``UTOOL[n]: X .. Y .. Z .. W .. P .. R ..`` (mm, deg), as on the Direct Entry screen."""
    line, values = numbered_line(FORMAT, "UTOOL", LABELS, tool, TOOL_NUMBERS)
    text = f"{line}  ! {ascii_text(tool.name, 40, drop=';')}"
    return ControllerExport(format=FORMAT, text=text, values=values)


# TP: a tool frame loaded from a position register whose six elements were set one by one,
# ``PR[n,1]=x ; .. PR[n,6]=r ; UTOOL[t]=PR[n] ;`` (ros-industrial-attic/robodk_postprocessors
# Fanuc_R30iA.py ``setTool``). A negative constant may be stored in parentheses, ``(-2.5)``.
_PR_ELEMENT = re.compile(rf"PR\[\s*(\d+)\s*,\s*([1-6])\s*\]\s*=\s*\(?\s*({NUMBER})\s*\)?")
_UTOOL_FROM_PR = re.compile(r"UTOOL\[\s*\d+\s*\]\s*=\s*PR\[\s*(\d+)\s*(?::[^\]]*)?\]")


def _parse_tp(text: str) -> tuple[FloatArray, FloatArray] | None:
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


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. W .. P .. R ..``, or TP ``PR[n,1..6]=.. ; UTOOL[t]=PR[n]`` ->
    (position (3,) mm, quaternion wxyz (4,))."""
    tp = _parse_tp(text)
    return tp if tp is not None else parse_labelled(FORMAT, LABELS, text)
