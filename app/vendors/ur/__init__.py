"""Universal Robots (CB3, e-Series): one package.

| module | what |
|---|---|
| text.py | URScript ``set_tcp(p[x,y,z,rx,ry,rz])`` (m, rad) and ``set_payload``, and its reader |
| file.py | a URScript file with a function per tool that sets its TCP and payload |

No tool numbers (one TCP at a time, named in the installation).

Protocol: ``ur_rtde`` (RTDE and the secondary client interface, URScript; TCP); its
connector is not written yet.
"""

from __future__ import annotations

from app.vendors.maker import FileModule, LiveTcp, Maker, TextModule, WireProtocol


def _text() -> TextModule:
    from app.vendors.ur import text

    return text


def _file() -> FileModule:
    from app.vendors.ur import file

    return file


#: RTDE (TCP) and the secondary client interface (TCP, URScript).
RTDE = WireProtocol(
    "ur_rtde",
    LiveTcp("tcp_offset"),
    None,
    services=(("rtde", 30004), ("secondary", 30002)),
)

MAKER = Maker(
    format="ur",
    name="Universal Robots",
    vendor_words=("universal",),
    vendor_initials=("ur",),
    file_kind="URScript",
    tool_numbers=None,
    text=_text,
    file=_file,
    protocols=(RTDE,),
)
