"""Controller text for a served TCP (KUKA, ABB, Fanuc, UR, Yaskawa, Techman)."""

from __future__ import annotations

import numpy as np

from app.exports import ToolData, export_tool
from app.models import TcpVersion, Tool
from app.schemas.tools import ControllerText


def controller_text(fmt: str, *, tool: Tool, version: TcpVersion) -> ControllerText:
    """{format, text, values} of a tool's version in a controller's own syntax."""
    load = tool.load or {}
    data = ToolData(
        slot=tool.slot,
        name=tool.name,
        position_mm=np.asarray(version.position_mm, dtype=float),
        quaternion_wxyz=np.asarray(version.quaternion, dtype=float),
        mass_kg=load.get("mass_kg"),
        cog_mm=np.asarray(load["cog_mm"], dtype=float) if load.get("cog_mm") else None,
    )
    export = export_tool(fmt, data)
    return ControllerText(format=export.format, text=export.text, values=export.values)
