"""FANUC (R-30iA, R-30iB): one package.

| module | what |
|---|---|
| text.py | ``UTOOL[n]: X .. W .. P .. R ..`` and its reader (also a TP program's PR form) |
| file.py | an ASCII TP program (.LS) that sets each tool frame when run |
| frame.py | a frame (base, fixed tool) as text and as the file its controller loads |
| rmi.py | the connector: Remote Motion Interface (B-84184EN), TCP 16001 |

Tool numbers: ``UTOOL[1..10]`` (R-30iB default; the count is a system setting). X Y Z W P R
are app.vendors.wpr's fixed-axis convention.
"""

from __future__ import annotations

from app.vendors.maker import (
    BySlot,
    FileModule,
    FrameModule,
    Maker,
    OpenSession,
    TextModule,
    WireProtocol,
)
from app.words import TcpZX, word

#: (first, last) tool number: UTOOL[1..10].
TOOL_NUMBERS = (1, 10)
#: (first, last) user frame number: UFRAME[1..9] (B-84184EN 2.3.9 FRC_WriteUFrameData: 1-9;
#: UFRAME 0 is the world frame, which no program writes).
FRAME_NUMBERS = (1, 9)


def _text() -> TextModule:
    from app.vendors.fanuc import text

    return text


def _file() -> FileModule:
    from app.vendors.fanuc import file

    return file


def _frame() -> FrameModule:
    from app.vendors.fanuc import frame

    return frame


def _rmi() -> OpenSession:
    from app.vendors.fanuc.rmi import FanucRmiConnector

    return FanucRmiConnector


#: Remote Motion Interface, FRC_Connect on 16001: UTOOL[n] and UFRAME[n] by number.
_UTOOLS, _UFRAMES = BySlot(TOOL_NUMBERS, "UTOOL[{}]"), BySlot(FRAME_NUMBERS, "UFRAME[{}]")
RMI = WireProtocol("fanuc_rmi", _UTOOLS, _rmi, default_port=16001, frames=_UFRAMES)

MAKER = Maker(
    format="fanuc",
    pose_format="fanuc_wpr",
    name="Fanuc",
    teaches=((word(TcpZX), "six-point"),),
    vendor_words=("fanuc",),
    file_kind="TP program (.LS)",
    tool_numbers=TOOL_NUMBERS,
    text=_text,
    file=_file,
    frame=_frame,
    protocols=(RMI,),
    active_tool="FANUC's active UTOOL",
    bare_flange="FANUC UTOOL 0",
)
