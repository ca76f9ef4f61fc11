"""Controller text for a served TCP, in each maker's format (app.vendors.registry.MAKERS)."""

from __future__ import annotations

from typing import Protocol

from app.jsontypes import JsonObject
from app.schemas.tools import ControllerText
from app.services.lifecycle.subject import Owned, Valued
from app.vendors.registry import export_tool
from app.vendors.tool import ToolData, ToolLoad, vec3, vec4
from app.words import ControllerFormat


class ServedTool(Owned, Protocol):
    """What serving a TCP reads of a tool: a models.Tool, or the hot read's few columns."""

    @property
    def slot(self) -> int | None: ...
    @property
    def load(self) -> JsonObject | None: ...
    @property
    def controller_symbol(self) -> str | None: ...


class ServedVersion(Valued, Protocol):
    """What serving a TCP reads of a version: a models.TcpVersion, or the hot read's columns
    (app.services.lifecycle.subject.Valued)."""


def tool_data(tool: ServedTool, version: ServedVersion) -> ToolData:
    """A tool's version as its controller holds it: the TCP, the load where its mass is
    stored (the centre of gravity where that is), the slot, name and controller symbol."""
    load = tool.load or {}
    mass, cog = load.get("mass_kg"), load.get("cog_mm")
    return ToolData(
        position_mm=vec3(version.position_mm),
        quaternion=vec4(version.quaternion),
        load=(
            ToolLoad(float(mass), vec3(cog) if isinstance(cog, list) and cog else None)
            if isinstance(mass, int | float)
            else None
        ),
        slot=tool.slot,
        name=tool.name,
        controller_symbol=tool.controller_symbol,
    )


def controller_text(
    fmt: ControllerFormat, *, tool: ServedTool, version: ServedVersion
) -> ControllerText:
    """{format, text, values} of a tool's version in a controller's own syntax."""
    export = export_tool(fmt, tool_data(tool, version))
    return ControllerText(format=export.format, text=export.text, values=export.values)
