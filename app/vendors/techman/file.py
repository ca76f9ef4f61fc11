"""Techman: TMscript lines that change the TCP, one per tool, for a TMflow Script or SET node.

Followed: the TMflow *Expression Editor and Listen Node* manual's ``ChangeTCP(float[],
float)`` (X Y Z mm, RX RY RZ deg, then the tool's mass kg), as app.vendors.techman.text sets
out with its sources; TMscript comments are ``//`` to the end of the line and array literals use
braces. Paste the line of the tool in use into the flow (a robot's table lists one line per
tool, each under a comment naming it).

What it changes, and how the controller merges it: a ChangeTCP line, when the flow runs it,
sets the current TCP (and mass) of the running project, until the project sets another one;
the TCP list (the tools stored on the controller) is untouched. Its header comment says so.

How it relates to a deployment (the ``techman`` connector, app.vendors.techman.tmflow): a
deployment sends the same ChangeTCP, through the Listen Node, to the project running now,
with the tool's mass (and its centre of gravity when tcpcal has the tool's load), and reads
the current TCP back: scope "live", it lasts until the next project start sets the TCP the
project was written with. This file's line is how the project itself sets the calibrated
TCP at its start (pasted into a SET or Script node before the motions that use the tool),
so that the calibration outlives a restart; the reconcile rounds show which TCP the robot
moves by either way. A tool re-calibrated later needs its line pasted again (a deployment
does not change the project).
"""

from __future__ import annotations

import re

from app.vendors.files import (
    ControllerFile,
    FileContext,
    FileTool,
    ParsedTool,
    header_comments,
    split_fitting,
)
from app.vendors.names import ascii_text, file_stem
from app.vendors.techman.text import export, parse
from app.vendors.text import parse_error

FORMAT = "techman"
LINE_WIDTH = 78
_CALL = re.compile(r"^\s*ChangeTCP\s*\(.*$", re.MULTILINE)
_MASS = re.compile(r"\}\s*,\s*([-+]?\d+(?:\.\d*)?)\s*\)")


def write(tools: list[FileTool], context: FileContext) -> ControllerFile:
    """Header comments, then per tool ``// <name>`` and its ChangeTCP line."""
    kept, left = split_fitting(tools, export, context)
    lines = header_comments(kept, left, context, _how(kept), "// ", LINE_WIDTH)
    for item in kept:
        call = export(item.data).text.split("  //", 1)[0]
        lines += [f"// {ascii_text(item.data.name, 40) or 'tool'}", call]
    if context.table or len(kept) != 1:
        name = "tcpcal_tools.txt"
    else:
        name = f"tcpcal_{file_stem(kept[0].data.name)}.txt"
    return ControllerFile(FORMAT, name, "\n".join(lines) + "\n", tuple(left))


def _how(kept: list[FileTool]) -> list[str]:
    """The header's sentences on what the lines change."""
    if not kept:
        return ["changes nothing: it holds no tool"]
    return [
        "each ChangeTCP line, run by the flow, sets the current TCP (and mass) of the running "
        "project until it sets another; the TCP list stored on the controller is untouched"
    ]


def read(text: str) -> list[ParsedTool]:
    """Every ChangeTCP line of the text."""
    tools = []
    for match in _CALL.finditer(text):
        position, quaternion = parse(match.group(0))
        mass = _MASS.search(match.group(0))
        tools.append(
            ParsedTool(None, None, position, quaternion, float(mass.group(1)) if mass else None)
        )
    if not tools:
        raise parse_error(FORMAT, "ChangeTCP({X,Y,Z,RX,RY,RZ},mass) lines", text)
    return tools
