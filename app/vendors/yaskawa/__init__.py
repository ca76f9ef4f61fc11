"""Yaskawa (Motoman YRC1000, DX200): one package.

| module | what |
|---|---|
| text.py | ``TOOL[n]: X Y Z Rx Ry Rz W Xg Yg Zg`` and its reader |
| file.py | TOOL.CND, the tool file as the controller saves and loads it, and `merge` |
| frame.py | a frame (base, fixed tool) as text and as the file its controller loads |
| hses.py | the connector: High Speed Ethernet Server (HSES manual, FS100 160766-1CD), UDP |
| hses_wire.py | HSES packets over UDP under one deadline, and the status codes in words |
| arms.py | the Motoman GP12's nominal DH table (the preset yaskawa_gp12) |

Tool numbers: tool files 0..63 (YRC1000 and DX200; NX100 had 0..23). X Y Z Rx Ry Rz are
app.vendors.wpr's fixed-axis convention.

Protocol: High Speed Ethernet Server (``yaskawa_hses``): robot control (UDP 10040: the
position read) and file control (UDP 10041: TOOL.CND saved and loaded).
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
from app.vendors.yaskawa.arms import ARMS

#: (first, last) tool number: tool files 0..63.
TOOL_NUMBERS = (0, 63)
#: (first, last) user frame number: user frames 1..63 (UFRAME.CND).
FRAME_NUMBERS = (1, 63)


def _text() -> TextModule:
    from app.vendors.yaskawa import text

    return text


def _file() -> FileModule:
    from app.vendors.yaskawa import file

    return file


def _frame() -> FrameModule:
    from app.vendors.yaskawa import frame

    return frame


def _hses() -> OpenSession:
    from app.vendors.yaskawa.hses import YaskawaHsesConnector

    return YaskawaHsesConnector


#: High Speed Ethernet Server: robot control (UDP) and file control (UDP), TOOL.CND's tools.
HSES = WireProtocol(
    "yaskawa_hses",
    BySlot(TOOL_NUMBERS, "TOOL.CND tool {}"),
    _hses,
    services=(("robot", 10040), ("file", 10041)),
    udp=True,
    frames=BySlot(FRAME_NUMBERS, "UFRAME.CND user frame {}"),
)

MAKER = Maker(
    format="yaskawa",
    pose_format="yaskawa_rxyz",
    name="Yaskawa",
    vendor_words=("yaskawa", "motoman"),
    file_kind="TOOL.CND",
    tool_numbers=TOOL_NUMBERS,
    text=_text,
    file=_file,
    frame=_frame,
    protocols=(HSES,),
    arms=ARMS,
    active_tool="Yaskawa's tool",
)
