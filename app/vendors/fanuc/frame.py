"""FANUC: a user frame as ``UFRAME[n]: X .. Y .. Z .. W .. P .. R ..`` (the text, as on the
frame's Direct Entry screen), an ASCII TP program (.LS) setting ``UFRAME[n]`` when run (the
file), and their reader.

Followed: the tool file's program (app.vendors.fanuc.file: the LS layout of programs saved by
R-30iA/R-30iB controllers, PR[100] as scratch, a negative constant in parentheses, 3
decimals as the controller shows frames) with ``UFRAME[n]=PR[100]`` in place of
``UTOOL[n]=PR[100]``: the TP instruction that copies a Cartesian position register into user
frame n (HandlingTool V9.40 sec. 7.20 as quoted in public notes; public TP programs set user
frames so, e.g. ``UFRAME[1]=PR[5:world] ;`` and ``PR[1]=UFRAME[1] ;`` in robot-cell
repositories). A user frame is X Y Z (mm) and W P R (deg) in the world frame, R = Rz(R)
Ry(P) Rx(W) (app.vendors.wpr). UFRAME[0] is the world frame itself: a frame needs a number
from 1. A fixed tool on FANUC is a remote TCP, whose point is a user frame: it is written the
same way.

What it changes, and how the controller merges it: running the program sets the user frames
it holds and PR[100]; every other user frame, the tool frames, UFRAME_NUM and UTOOL_NUM stay
as they are. Its remarks say so.
"""

from __future__ import annotations

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.vendors.fanuc import FRAME_NUMBERS
from app.vendors.fanuc.file import (
    REMARK_CHARS,
    SCRATCH_PR,
    frame_lines,
    frames_of_program,
    ls_program,
    remark,
)
from app.vendors.fanuc.text import FORMAT, LABELS, parse_tp
from app.vendors.files import (
    ControllerFile,
    FileContext,
    as_utc,
    header_lines,
    left_out_lines,
    split_fitting,
    wrap,
)
from app.vendors.frame import NOUN, FileFrame, FrameData, ParsedFrame, frame_number
from app.vendors.names import ascii_text
from app.vendors.text import ControllerExport
from app.vendors.wpr import fields_text, named_values, parse_labelled, xyz_wpr

WORD = "UFRAME"
TABLE_PROGRAM = "TCPUFALL"


def user_frame(frame: FrameData) -> int:
    """The frame's UFRAME number (from 1: UFRAME[0] is the world frame); 422 at "slot"."""
    slot = frame_number(frame, "FANUC", "UFRAME[n]")
    if slot < 1:
        raise InvalidInput(
            "invalid-options",
            f"UFRAME[{slot}] is not a user frame (UFRAME[0] is the world frame): set the "
            "frame's slot to its user frame number, from 1",
            loc=("slot",),
        )
    return frame_number(frame, "FANUC", "UFRAME[n]", FRAME_NUMBERS)


def export(frame: FrameData) -> ControllerExport:
    """``UFRAME[n]: X .. Y .. Z .. W .. P .. R ..  ! name`` (mm, deg)."""
    slot = user_frame(frame)
    six = xyz_wpr(frame)
    values: dict[str, object] = {"slot": slot, **named_values(LABELS, six)}
    text = f"{WORD}[{slot}]: {fields_text(LABELS, six)}  ! {ascii_text(frame.name, 40, drop=';')}"
    return ControllerExport(format=FORMAT, text=text, values=values)


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """``X .. Y .. Z .. W .. P .. R ..``, or TP ``PR[n,1..6]=.. ; UFRAME[u]=PR[n]`` (one user
    frame) -> (position (3,) mm, quaternion wxyz (4,))."""
    tp = parse_tp(text, None, WORD)
    return tp if tp is not None else parse_labelled(FORMAT, LABELS, text)


def program_name(frames: list[FileFrame], context: FileContext) -> str:
    """TCPUF02 for user frame 2's program, TCPUFALL for a robot's table."""
    if context.table or len(frames) != 1:
        return TABLE_PROGRAM
    return f"TCPUF{frames[0].data.slot:02d}"


def _check(frame: FrameData) -> None:
    user_frame(frame)
    xyz_wpr(frame)


def _how(kept: list[FileFrame]) -> list[str]:
    """The remarks on what the program changes when it is run."""
    if not kept:
        return ["changes nothing: it holds no frame"]
    slots = sorted(f.data.slot or 0 for f in kept)
    return [
        f"changes only user frame(s) {', '.join(str(n) for n in slots)}",
        "every other user frame and the tool frames are untouched",
        f"PR[{SCRATCH_PR}] carries the numbers: its old value is lost",
        "UFRAME_NUM and UTOOL_NUM stay as they are",
    ]


def write(frames: list[FileFrame], context: FileContext) -> ControllerFile:
    """/PROG, /ATTR, /MN (remarks, then PR element assignments and UFRAME[n]=PR[100] per
    frame), /POS, /END."""
    kept, left = split_fitting(frames, _check, context)
    name = program_name(frames, context)
    sentences = [*header_lines(kept, context, NOUN), *left_out_lines(left), *_how(kept)]
    body = [remark(piece) for s in sentences for piece in wrap(s, REMARK_CHARS)]
    if kept:
        body.append(f"PR[{SCRATCH_PR}]=LPOS    ;")
    for item in sorted(kept, key=lambda f: f.data.slot or 0):
        body += frame_lines(WORD, item.data.slot, item.data.name, xyz_wpr(item.data))
    stamps = [as_utc(f.provenance.calibrated_at) for f in kept if f.provenance is not None]
    comment = "tcpcal frames" if context.table else f"tcpcal UFRAME {kept[0].data.slot}"
    text = ls_program(name, comment, body, max(stamps) if stamps else None)
    return ControllerFile(FORMAT, f"{name}.LS", text, tuple(left))


def read(text: str) -> list[ParsedFrame]:
    """Every ``UFRAME[n]=PR[m]`` of a TP program, with the six PR[m,i] set before it."""
    return [
        ParsedFrame(slot, name, position, quaternion)
        for slot, name, position, quaternion in frames_of_program(text, WORD)
    ]
