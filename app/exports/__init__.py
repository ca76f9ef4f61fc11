"""Controller text for a TCP: what a technician pastes into a KUKA, ABB, Fanuc, UR, Yaskawa
or Techman controller, and the parsers that read that text back.

Pure numpy/scipy: no web framework, database or pydantic here.
"""

from __future__ import annotations

from collections.abc import Callable

from app.errors import InvalidInput
from app.exports.abb import export_abb, parse_abb, rapid_identifier
from app.exports.base import ControllerExport, FloatArray, ToolData
from app.exports.kuka import export_kuka, parse_kuka
from app.exports.ur import export_ur, parse_ur
from app.exports.wpr import (
    export_fanuc,
    export_techman,
    export_yaskawa,
    parse_fanuc,
    parse_techman,
    parse_yaskawa,
)

CONTROLLER_FORMATS: tuple[str, ...] = ("kuka", "abb", "fanuc", "ur", "yaskawa", "techman")

_EXPORTERS: dict[str, Callable[[ToolData], ControllerExport]] = {
    "kuka": export_kuka,
    "abb": export_abb,
    "fanuc": export_fanuc,
    "ur": export_ur,
    "yaskawa": export_yaskawa,
    "techman": export_techman,
}
#: The file a technician saves the text as: what each controller's tooling loads.
FILE_EXTENSIONS: dict[str, str] = {
    "kuka": "dat",  # a $config.dat / TOOL_DATA fragment
    "abb": "mod",  # a RAPID module's tooldata declaration
    "fanuc": "ls",  # a TP program source
    "ur": "script",  # URScript
    "yaskawa": "cnd",  # TOOL.CND
    "techman": "txt",
}


def file_name(fmt: str, tool_name: str, slot: int | None) -> str:
    """A file name for a tool's controller text: e.g. tool3_torch.dat (letters kept safe)."""
    safe = "".join(c if c.isascii() and (c.isalnum() or c in "-_") else "_" for c in tool_name)
    prefix = f"tool{slot}_" if slot is not None else ""
    return f"{prefix}{safe.strip('_') or 'tool'}.{FILE_EXTENSIONS[_check_format(fmt)]}"


_PARSERS: dict[str, Callable[[str], tuple[FloatArray, FloatArray]]] = {
    "kuka": parse_kuka,
    "abb": parse_abb,
    "fanuc": parse_fanuc,
    "ur": parse_ur,
    "yaskawa": parse_yaskawa,
    "techman": parse_techman,
}


def _check_format(fmt: str) -> str:
    if fmt not in CONTROLLER_FORMATS:
        raise InvalidInput(
            "unknown-format",
            f"unknown controller format {fmt!r}; known: {', '.join(CONTROLLER_FORMATS)}",
            loc=("format",),
        )
    return fmt


def export_tool(fmt: str, tool: ToolData) -> ControllerExport:
    """The tool's TCP (and load where the controller stores it) as controller `fmt`'s text."""
    return _EXPORTERS[_check_format(fmt)](tool)


def parse_controller_text(fmt: str, text: str) -> tuple[FloatArray, FloatArray]:
    """Read controller `fmt`'s tool text -> (position (3,) mm, quaternion [w, x, y, z] (4,))."""
    if not isinstance(text, str):
        raise InvalidInput("invalid-pose", "controller text must be a string", loc=("text",))
    return _PARSERS[_check_format(fmt)](text)


__all__ = [
    "CONTROLLER_FORMATS",
    "ControllerExport",
    "ToolData",
    "export_tool",
    "parse_controller_text",
    "rapid_identifier",
]
