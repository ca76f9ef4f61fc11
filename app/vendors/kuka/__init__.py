"""KUKA (KRC, KSS 8.x): one package.

| module | what |
|---|---|
| text.py | KRL structure values (read and written once) and ``$TOOL_DATA[n]={X,Y,Z,A,B,C}`` |
| file.py | the tool's lines of ``$config.dat`` (TOOL_DATA, TOOL_NAME, LOAD_DATA) |
| frame.py | a frame (base, fixed tool) as text and as the file its controller loads |
| kvp.py | the connector: KUKAVARPROXY (OpenShowVar), TCP 7000 |

Tool numbers: ``$TOOL_DATA[1..16]`` (KSS 8.x, $config.dat ``DECL FRAME TOOL_DATA[16]``).
Frame numbers: ``BASE_DATA[1..32]`` (``DECL FRAME BASE_DATA[32]``); a fixed tool is a base
used with ``$IPO_MODE #TCP``.
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
from app.words import Abc2Point, AbcWorld, word

#: (first, last) tool number: $TOOL_DATA[1..16].
TOOL_NUMBERS = (1, 16)
#: (first, last) base number: BASE_DATA[1..32] ($config.dat ``DECL FRAME BASE_DATA[32]``).
FRAME_NUMBERS = (1, 32)


def _text() -> TextModule:
    from app.vendors.kuka import text

    return text


def _file() -> FileModule:
    from app.vendors.kuka import file

    return file


def _frame() -> FrameModule:
    from app.vendors.kuka import frame

    return frame


def _kvp() -> OpenSession:
    from app.vendors.kuka.kvp import KukaKvpConnector

    return KukaKvpConnector


#: $TOOL_DATA[n] and BASE_DATA[n] by number.
_TOOLS, _BASES = BySlot(TOOL_NUMBERS, "$TOOL_DATA[{}]"), BySlot(FRAME_NUMBERS, "BASE_DATA[{}]")
#: A pose read is refused in external-TCP mode (kvp.py: the tool stands fixed in the cell).
KVP = WireProtocol(
    "kuka_kvp",
    _TOOLS,
    _kvp,
    default_port=7000,
    frames=_BASES,
    refused_when="in `$IPO_MODE #TCP`",
)

MAKER = Maker(
    format="kuka",
    pose_format="kuka_abc",
    name="KUKA",
    vendor_words=("kuka",),
    file_kind="$config.dat lines",
    tool_numbers=TOOL_NUMBERS,
    text=_text,
    file=_file,
    frame=_frame,
    protocols=(KVP,),
    teaches=((word(Abc2Point), "ABC 2-point"), (word(AbcWorld), "ABC world 5D/6D")),
    active_tool="KUKA $ACT_TOOL",
    bare_flange="KUKA $NULLFRAME",
    working_axis="x",
)
