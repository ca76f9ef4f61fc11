"""A tool as a controller holds it: the one `ToolData`, written by the exports and files,
and read and written by the connectors.

The frame is the tool's TCP in the flange frame: a position in mm and a unit quaternion
w, x, y, z (tcpcal's convention; each maker's package converts to its own). The load, the
tool's number (slot), its name and its controller symbol are there where the text, the file
or the controller uses them; a connector's read gives the frame and the load only.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol

Vec3 = tuple[float, float, float]
Vec4 = tuple[float, float, float, float]


class Posed(Protocol):
    """What carries a pose a controller's text prints: a position (mm) and a unit quaternion
    w, x, y, z (a ToolData's TCP, a FrameData's frame)."""

    @property
    def position_mm(self) -> Vec3: ...
    @property
    def quaternion(self) -> Vec4: ...


def vec3(values: Iterable[float]) -> Vec3:
    """Three floats; ValueError naming the count otherwise."""
    x, y, z = _floats(values, 3)
    return x, y, z


def vec4(values: Iterable[float]) -> Vec4:
    """Four floats; ValueError naming the count otherwise."""
    w, x, y, z = _floats(values, 4)
    return w, x, y, z


def _floats(values: Iterable[float], count: int) -> list[float]:
    numbers = [float(v) for v in values]
    if len(numbers) != count:
        raise ValueError(f"expected {count} numbers, got {len(numbers)}: {numbers}")
    return numbers


@dataclass(frozen=True)
class ToolLoad:
    """The tool's mass (kg) and its centre of gravity in the flange frame (mm); `cog_mm` None
    where it is not known (a text that holds the load then says to set it, a connector writes
    the flange's origin, as a deployment does)."""

    mass_kg: float
    cog_mm: Vec3 | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass_kg", float(self.mass_kg))
        if self.cog_mm is not None:
            object.__setattr__(self, "cog_mm", vec3(self.cog_mm))

    @property
    def cog_or_origin(self) -> Vec3:
        """The centre of gravity, the flange's origin where it is not known."""
        return self.cog_mm if self.cog_mm is not None else (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ToolData:
    """A tool frame in the flange frame (position mm, unit quaternion w, x, y, z), its load
    where known, and what names it in a controller's text: its tool number (slot), its name,
    and (under a protocol addressing tools by symbol) its symbol "TASK/MODULE/SYMBOL"
    (validated where the tool is stored), so that a file names the data the robot's programs
    use. Lists and arrays are stored as tuples of floats (so two reads compare with ==)."""

    position_mm: Vec3
    quaternion: Vec4
    load: ToolLoad | None = None
    slot: int | None = None
    name: str = ""
    controller_symbol: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "position_mm", vec3(self.position_mm))
        object.__setattr__(self, "quaternion", vec4(self.quaternion))


def finite_tool_data(data: ToolData) -> None:
    """ValueError when a position, quaternion or load value is not a finite number."""
    values = [*data.position_mm, *data.quaternion]
    if data.load is not None:
        values += [data.load.mass_kg, *data.load.cog_or_origin]
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"tool data holds a value that is not a finite number: {values}")
