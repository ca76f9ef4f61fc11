"""Controller text for a TCP: what a technician pastes into a KUKA, ABB, Fanuc, UR, Yaskawa
or Techman controller (the short line of the JSON `controller.text`), the file each
controller loads as it is (one module per format: krl_file, rapid_file, tp_file, cnd_file,
urscript_file, tmscript_file), and the parsers that read both back.

Pure numpy/scipy: no web framework, database or pydantic here.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Literal, get_args

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.exports import (
    cnd_file,
    krl_file,
    rapid_file,
    tmscript_file,
    tp_file,
    urscript_file,
)
from app.exports.abb import export_abb, parse_abb, rapid_identifier
from app.exports.base import ControllerExport, ToolData
from app.exports.files import (
    ControllerFile,
    FileContext,
    FileTool,
    LeftOut,
    ParsedTool,
    Provenance,
)
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

#: The controllers' text formats (`?format=` and `controller.format`); the tuple is read off it.
ControllerFormat = Literal["kuka", "abb", "fanuc", "ur", "yaskawa", "techman"]
CONTROLLER_FORMATS: tuple[ControllerFormat, ...] = get_args(ControllerFormat)

_EXPORTERS: dict[str, Callable[[ToolData], ControllerExport]] = {
    "kuka": export_kuka,
    "abb": export_abb,
    "fanuc": export_fanuc,
    "ur": export_ur,
    "yaskawa": export_yaskawa,
    "techman": export_techman,
}
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


_FILE_WRITERS: dict[str, Callable[[list[FileTool], FileContext], ControllerFile]] = {
    "kuka": krl_file.write,
    "abb": rapid_file.write,
    "fanuc": tp_file.write,
    "ur": urscript_file.write,
    "yaskawa": cnd_file.write,
    "techman": tmscript_file.write,
}
_FILE_READERS: dict[str, Callable[[str], list[ParsedTool]]] = {
    "kuka": krl_file.read,
    "abb": rapid_file.read,
    "fanuc": tp_file.read,
    "ur": urscript_file.read,
    "yaskawa": cnd_file.read,
    "techman": tmscript_file.read,
}
#: What each format's file is, in a few words (the console's download buttons, the README).
FILE_KINDS: dict[str, str] = {
    "kuka": "$config.dat lines",
    "abb": "RAPID module",
    "fanuc": "TP program (.LS)",
    "ur": "URScript",
    "yaskawa": "TOOL.CND",
    "techman": "TMscript line",
}
# A robot's vendor as people write it -> the controller format its tools are loaded in.
_VENDOR_FORMATS = (
    ("kuka", "kuka"),
    ("abb", "abb"),
    ("fanuc", "fanuc"),
    ("universal", "ur"),
    ("yaskawa", "yaskawa"),
    ("motoman", "yaskawa"),
    ("techman", "techman"),
)


def controller_file(
    fmt: str, tools: Sequence[FileTool], context: FileContext | None = None
) -> ControllerFile:
    """The file controller `fmt` loads for one tool, or (context.table) for a robot's tools."""
    return _FILE_WRITERS[_check_format(fmt)](list(tools), context or FileContext())


def parse_controller_file(fmt: str, text: str) -> list[ParsedTool]:
    """Every tool of a controller `fmt` file, as `controller_file` writes it (or the
    controller saves it)."""
    if not isinstance(text, str):
        raise InvalidInput("invalid-pose", "controller file must be text", loc=("text",))
    return _FILE_READERS[_check_format(fmt)](text)


def vendor_formats(vendor: str | None) -> tuple[str, ...]:
    """The controller formats a robot of `vendor` loads (every format when not known)."""
    key = (vendor or "").lower()
    for word, fmt in _VENDOR_FORMATS:
        if word in key:
            return (fmt,)
    words = set(re.findall(r"[a-z]+", key))
    if "ur" in words:
        return ("ur",)
    if "tm" in words:
        return ("techman",)
    return CONTROLLER_FORMATS


def parse_controller_text(fmt: str, text: str) -> tuple[FloatArray, FloatArray]:
    """Read controller `fmt`'s tool text -> (position (3,) mm, quaternion [w, x, y, z] (4,))."""
    if not isinstance(text, str):
        raise InvalidInput("invalid-pose", "controller text must be a string", loc=("text",))
    return _PARSERS[_check_format(fmt)](text)


__all__ = [
    "CONTROLLER_FORMATS",
    "FILE_KINDS",
    "ControllerExport",
    "ControllerFile",
    "ControllerFormat",
    "FileContext",
    "FileTool",
    "LeftOut",
    "ParsedTool",
    "Provenance",
    "ToolData",
    "controller_file",
    "export_tool",
    "parse_controller_file",
    "parse_controller_text",
    "rapid_identifier",
    "vendor_formats",
]
