"""Controller text for a served TCP (KUKA, ABB, Fanuc, UR, Yaskawa, Techman)."""

from __future__ import annotations

from datetime import datetime
from typing import Protocol

import numpy as np

from app.exports import ToolData, export_tool
from app.jsontypes import JsonArray, JsonObject
from app.schemas.tools import ControllerText
from app.words import MethodName


class ServedTool(Protocol):
    """What serving a TCP reads of a tool: a models.Tool, or the hot read's few columns."""

    @property
    def id(self) -> str: ...
    @property
    def robot_id(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def slot(self) -> int | None: ...
    @property
    def load(self) -> JsonObject | None: ...
    @property
    def controller_symbol(self) -> str | None: ...


class ServedVersion(Protocol):
    """What serving a TCP reads of a version: a models.TcpVersion, or the hot read's columns."""

    @property
    def version(self) -> int: ...
    @property
    def position_mm(self) -> JsonArray: ...
    @property
    def quaternion(self) -> JsonArray: ...
    @property
    def source(self) -> MethodName: ...
    @property
    def created_at(self) -> datetime: ...


def controller_text(fmt: str, *, tool: ServedTool, version: ServedVersion) -> ControllerText:
    """{format, text, values} of a tool's version in a controller's own syntax."""
    load = tool.load or {}
    data = ToolData(
        slot=tool.slot,
        name=tool.name,
        position_mm=np.asarray(version.position_mm, dtype=float),
        quaternion_wxyz=np.asarray(version.quaternion, dtype=float),
        mass_kg=load.get("mass_kg"),
        cog_mm=np.asarray(load["cog_mm"], dtype=float) if load.get("cog_mm") else None,
        controller_symbol=tool.controller_symbol,
    )
    export = export_tool(fmt, data)
    return ControllerText(format=export.format, text=export.text, values=export.values)
