"""A frame as a controller holds it: the one `FrameData` each maker's frame module
(app.vendors.<maker>.frame) writes as its text and its file, and `ParsedFrame`, what a
reader gives back.

A frame's value is a pose in the robot's base (world) frame, a position in mm and a unit
quaternion w, x, y, z (contract v1.4 "Frames"): a base the robot's points are taught in (a
base, a work object, a user frame, a feature, as each maker names it), or, for a fixed tool,
the stationary TCP in that frame. Its number (slot), its name and its controller
symbol are there where the text or the file names it. A file holds one frame (GET
/v1/frames/{id}/frame, Accept: text/plain) or all of a robot's frames (GET
/v1/robots/{id}/frame-table), with the header app.vendors.files writes for tools, its noun
"frame" (`NOUN`).
"""

from __future__ import annotations

from dataclasses import dataclass

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.vendors.files import Provenance
from app.vendors.tool import Vec3, Vec4, vec3, vec4

#: What a frame file's header calls what it holds.
NOUN = "frame"


@dataclass(frozen=True)
class FrameData:
    """A frame in the robot's base frame (position mm, unit quaternion w, x, y, z), whether
    it is a fixed tool's stationary TCP (`fixed_tool`) or a base, and what names it in a
    controller's text: its number (slot), its name, its symbol "TASK/MODULE/SYMBOL"."""

    position_mm: Vec3
    quaternion: Vec4
    fixed_tool: bool = False
    slot: int | None = None
    name: str = ""
    controller_symbol: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "position_mm", vec3(self.position_mm))
        object.__setattr__(self, "quaternion", vec4(self.quaternion))

    @property
    def kind_words(self) -> str:
        """What the frame is, in words: "fixed tool" or "base"."""
        return "fixed tool" if self.fixed_tool else "base"


@dataclass(frozen=True)
class FileFrame:
    """A frame as a file holds it: the controller data, and the header's provenance."""

    data: FrameData
    provenance: Provenance | None = None


@dataclass(frozen=True)
class ParsedFrame:
    """One frame read back from a controller's text or file (None where it does not say;
    `fixed_tool` None where the file does not tell a base from a fixed tool)."""

    slot: int | None
    name: str | None
    position_mm: FloatArray
    quaternion_wxyz: FloatArray
    fixed_tool: bool | None = None


def frame_number(
    frame: FrameData, maker: str, named: str, numbers: tuple[int, int] | None = None
) -> int:
    """The frame's number, which `named` (how the maker names frame n) needs, within the
    maker's frame `numbers` (first, last) when given; 422 at "slot" naming the maker when the
    frame has none or one outside them."""
    if frame.slot is None:
        raise InvalidInput(
            "invalid-options",
            f"a {maker} frame needs its number (slot) for {named}; frame {frame.name!r} has "
            "none: set the frame's slot",
            loc=("slot",),
        )
    if numbers is not None and not numbers[0] <= frame.slot <= numbers[1]:
        raise InvalidInput(
            "invalid-options",
            f"slot {frame.slot} of frame {frame.name!r} is not a {maker} frame number for "
            f"{named}: set the frame's slot to one of {numbers[0]}..{numbers[1]}",
            loc=("slot",),
        )
    return frame.slot
