"""Universal Robots (CB3, e-Series): one package.

| module | what |
|---|---|
| text.py | URScript ``set_tcp(p[x,y,z,rx,ry,rz])`` (m, rad) and ``set_payload``, and its reader |
| file.py | a URScript file with a function per tool that sets its TCP and payload |
| frame.py | a frame (base, fixed tool) as text and as the file its controller loads |
| rtde.py | the connector: tcp_offset over RTDE (30004), set_tcp on the secondary (30002) |
| arms.py | the e-Series arms' nominal DH tables (the presets ur3e, ur5e, ur10e, ur16e) |

No tool numbers (one TCP at a time, named in the installation).

Protocol: ``ur_rtde`` (RTDE and the secondary client interface, URScript; TCP). A
deployment is live (``set_tcp`` holds until the next program start sets the installation's
TCP); the file is what a program keeps.
"""

from __future__ import annotations

from app.vendors.maker import (
    ByValue,
    FileModule,
    FrameModule,
    LiveTcp,
    Maker,
    OpenSession,
    TextModule,
    WireProtocol,
)
from app.vendors.ur.arms import ARMS


def _text() -> TextModule:
    from app.vendors.ur import text

    return text


def _file() -> FileModule:
    from app.vendors.ur import file

    return file


def _frame() -> FrameModule:
    from app.vendors.ur import frame

    return frame


def _rtde() -> OpenSession:
    from app.vendors.ur.rtde import UrRtdeConnector

    return UrRtdeConnector


#: RTDE (TCP) and the secondary client interface (TCP, URScript).
RTDE = WireProtocol(
    "ur_rtde",
    LiveTcp("tcp_offset"),
    _rtde,
    services=(("rtde", 30004), ("secondary", 30002)),
    frames=ByValue("installation feature", live=False),
)

MAKER = Maker(
    format="ur",
    pose_format="ur_rotvec",
    name="Universal Robots",
    vendor_words=("universal",),
    vendor_initials=("ur",),
    file_kind="URScript",
    tool_numbers=None,
    text=_text,
    file=_file,
    frame=_frame,
    protocols=(RTDE,),
    arms=ARMS,
    bare_flange="UR tcp_offset",
)
