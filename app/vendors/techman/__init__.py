"""Techman (TM robots, TMflow): one package.

| module | what |
|---|---|
| text.py | TMscript ``ChangeTCP({X,Y,Z,RX,RY,RZ},mass)`` and its reader |
| file.py | TMscript lines, one ChangeTCP per tool, for a Script or SET node |
| frame.py | a frame (base, fixed tool) as text and as the file its controller loads |
| tmflow.py | the connector: the Listen Node (ChangeTCP) and the Ethernet Slave (the data table) |
| arms.py | the TM5-900's nominal DH table (the preset tm5_900) |

No tool numbers (TCPs are named in TMflow's TCP list). X Y Z RX RY RZ are taken as
app.vendors.wpr's fixed-axis convention.

Protocol: ``techman`` (TMflow's Listen Node, ChangeTCP, and Ethernet Slave, the data table;
TCP 5890 and 5891): it writes the robot's one live TCP, scope "live" (the next project start
sets its own TCP).
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
from app.vendors.techman.arms import ARMS


def _text() -> TextModule:
    from app.vendors.techman import text

    return text


def _file() -> FileModule:
    from app.vendors.techman import file

    return file


def _frame() -> FrameModule:
    from app.vendors.techman import frame

    return frame


def _tmflow() -> OpenSession:
    from app.vendors.techman.tmflow import TechmanConnector

    return TechmanConnector


#: TMflow: Listen Node (TCP, ChangeTCP) and Ethernet Slave (TCP, the data table).
TMFLOW = WireProtocol(
    "techman",
    LiveTcp("current TCP"),
    _tmflow,
    services=(("listen_node", 5890), ("ethernet_slave", 5891)),
    frames=ByValue("current base", live=True),
)

MAKER = Maker(
    format="techman",
    pose_format="techman_rxyz",
    name="Techman",
    vendor_words=("techman",),
    vendor_initials=("tm",),
    file_kind="TMscript line",
    tool_numbers=None,
    text=_text,
    file=_file,
    frame=_frame,
    protocols=(TMFLOW,),
    arms=ARMS,
    bare_flange="Techman TCP",
)
