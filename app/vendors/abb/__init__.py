"""ABB (IRC5, OmniCore): one package.

| module | what |
|---|---|
| text.py | RAPID ``tooldata`` values (read and written once) and ``PERS tooldata name:=[...];`` |
| file.py | a RAPID module that assigns each tool's tooldata |
| frame.py | a frame (base, fixed tool) as text and as the file its controller loads |
| symbol.py | "TASK/MODULE/SYMBOL", where a tool's tooldata lives (its ``controller_symbol``) |
| rws.py | the connector: Robot Web Services 1.0 (RobotWare 6) and 2.0 (RobotWare 7) |

No tool numbers: a tooldata is a named RAPID variable.
"""

from __future__ import annotations

from app.vendors.abb.symbol import symbol_problem
from app.vendors.maker import (
    BySymbol,
    FileModule,
    FrameModule,
    Maker,
    OpenSession,
    TextModule,
    WireProtocol,
)
from app.words import TcpZX, word


def _text() -> TextModule:
    from app.vendors.abb import text

    return text


def _file() -> FileModule:
    from app.vendors.abb import file

    return file


def _frame() -> FrameModule:
    from app.vendors.abb import frame

    return frame


def _rws() -> OpenSession:
    from app.vendors.abb.rws import AbbRwsConnector

    return AbbRwsConnector


_BY_SYMBOL = BySymbol(
    'RAPID symbol: set the tool\'s controller_symbol as "TASK/MODULE/SYMBOL", '
    'e.g. "T_ROB1/user/tTorch"',
    symbol_problem,
)
#: A frame: a PERS wobjdata (a base) or a stationary tooldata (a fixed tool) by its symbol.
_FRAME_BY_SYMBOL = BySymbol(
    'RAPID symbol: set the frame\'s controller_symbol as "TASK/MODULE/SYMBOL" of its '
    'wobjdata (a base) or stationary tooldata (a fixed tool), e.g. "T_ROB1/user/wobjFixA"',
    symbol_problem,
)


def _rws_protocol(name: str, port: int) -> WireProtocol:
    """A Robot Web Services protocol on `port`: tools and frames by RAPID symbol; it logs
    in as the user set, else ABB's factory user (rws.py's DEFAULT_USER); a pose read's live
    tool is unread (rws.py's read_pose: LiveTool(None, None))."""
    return WireProtocol(
        name,
        _BY_SYMBOL,
        _rws,
        default_port=port,
        frames=_FRAME_BY_SYMBOL,
        user="the RWS user",
        default_user="ABB's factory user",
        live_tool_unsaid="RWS does not say which tooldata a program uses",
    )


#: RobotWare 6 Robot Web Services, HTTP + Digest.
RWS1 = _rws_protocol("abb_rws1", 80)
#: RobotWare 7 Robot Web Services 2.0, HTTPS + Basic.
RWS2 = _rws_protocol("abb_rws2", 443)

MAKER = Maker(
    format="abb",
    pose_format="xyz_wxyz",
    name="ABB",
    teaches=((word(TcpZX), "TCP&Z,X"),),
    vendor_words=("abb",),
    file_kind="RAPID module",
    tool_numbers=None,
    text=_text,
    file=_file,
    frame=_frame,
    protocols=(RWS1, RWS2),
)
