"""A tool for the exports' tests, written as a tool's row holds it: slot, name, TCP, and the
load's mass and centre of gravity each where known."""

from __future__ import annotations

from collections.abc import Iterable

from app.vendors.tool import ToolData, ToolLoad, vec3, vec4


def tool_data(
    slot: int | None,
    name: str,
    position: Iterable[float],
    quaternion: Iterable[float],
    mass: float | None = None,
    cog: Iterable[float] | None = None,
    symbol: str | None = None,
) -> ToolData:
    """ToolData with a load when `mass` is given (its centre of gravity when `cog` is)."""
    load = None if mass is None else ToolLoad(mass, None if cog is None else vec3(cog))
    return ToolData(vec3(position), vec4(quaternion), load, slot, name, symbol)
