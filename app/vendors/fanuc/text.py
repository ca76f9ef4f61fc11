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
from app.errors import InvalidInput
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
_FROM_PR = r"\[\s*(\d+)\s*\]\s*=\s*PR\[\s*(\d+)\s*(?::[^\]]*)?\]"
#: ``UTOOL[t]=PR[n]`` (and a user frame's ``UFRAME[u]=PR[n]``): a frame loaded from a register.
FROM_PR = {word: re.compile(word + _FROM_PR) for word in ("UTOOL", "UFRAME")}


def _assignment(text: str, tool: int | None, word: str) -> re.Match[str] | None:
    """The last ``UTOOL[t]=PR[n]`` (`word` UTOOL, or UFRAME) of `tool` (of the one frame the
    text loads when None); None when the text loads no such frame from a register. Several
    numbers and none asked for, or one asked for that the text does not load: 422 naming
    those it does."""
    assigns = list(FROM_PR[word].finditer(text))
    if not assigns:
        return None
    numbers = sorted({int(a.group(1)) for a in assigns})
    found = " and ".join(f"{word}[{n}]" for n in numbers)
    if tool is None and len(numbers) > 1:
        raise InvalidInput(
            "invalid-pose",
            f"cannot read fanuc {word} data: the program loads {found} from position "
            "registers and the text's one frame would be one of them under no number; read "
            "it for one number, or keep only that frame's lines",
            loc=("text",),
        )
    wanted = numbers[0] if tool is None else tool
    mine = [a for a in assigns if int(a.group(1)) == wanted]
    if not mine:
        raise InvalidInput(
            "invalid-pose",
            f"cannot read fanuc {word} data: the program loads no {word}[{wanted}] from a "
            f"position register, only {found}",
            loc=("text",),
        )
    return mine[-1]


def parse_tp(
    text: str, tool: int | None, word: str = "UTOOL"
) -> tuple[FloatArray, FloatArray] | None:
    """The frame a TP program leaves in `tool` (of `word`, UTOOL or UFRAME) once it has run:
    its last ``UTOOL[t]=PR[n]``, with each element of PR[n] as last set before that line (a
    later assignment overwrites an earlier one; an element set after it is not copied)."""
    assign = _assignment(text, tool, word)
    if assign is None:
        return None
    register = assign.group(2)
    elements: dict[int, float] = {}
    for match in _PR_ELEMENT.finditer(text[: assign.start()]):
        if match.group(1) == register:
            elements[int(match.group(2))] = float(match.group(3))
    if len(elements) < 6:
        return None
    return tcp_from_numbers([elements[i] for i in range(1, 7)])


def parse(text: str, tool: int | None = None) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. W .. P .. R ..``, or TP ``PR[n,1..6]=.. ; UTOOL[t]=PR[n]`` ->
    (position (3,) mm, quaternion wxyz (4,)).

    A TP program is read as the controller holds tool frame `tool` after running it: the
    last ``UTOOL[tool]=PR[n]``, with PR[n]'s elements as they stand at that line. With
    `tool` None the program must load one tool number only (as often as it likes): one
    that loads UTOOL[1] and UTOOL[2] leaves both frames held, and the last assignment is
    not the selected tool (``UTOOL_NUM`` selects, ``UTOOL[t]=`` only writes frame t), so
    reading it would hand back one of two frames as the text's TCP with no number to say
    which; that is a 422 naming the numbers found instead."""
    tp = parse_tp(text, tool)
    return tp if tp is not None else parse_labelled(FORMAT, LABELS, text)
