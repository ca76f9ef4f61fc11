"""Controller text for a served frame (contract v1.4 "Frame touches and methods": `?format=`
adds ``"controller": {"format", "text", "values"}``): the frame's active version in a
controller's own words (app.vendors.<maker>.frame), as a tool's TCP is
(app.services.tools.controller_text)."""

from __future__ import annotations

from typing import Protocol

from app.schemas.tools import ControllerText
from app.services.lifecycle.subject import Owned, Valued
from app.vendors.frame import FrameData
from app.vendors.registry import export_frame
from app.vendors.tool import vec3, vec4
from app.words import ControllerFormat


class ServedFrame(Owned, Protocol):
    """What serving a frame's text reads of it: a models.Frame."""

    @property
    def slot(self) -> int | None: ...
    @property
    def kind(self) -> str: ...
    @property
    def controller_symbol(self) -> str | None: ...


def frame_data(frame: ServedFrame, version: Valued) -> FrameData:
    """A frame's version as its controller holds it: the pose, whether it is a fixed tool,
    its number, name and symbol."""
    return FrameData(
        position_mm=vec3(version.position_mm),
        quaternion=vec4(version.quaternion),
        fixed_tool=frame.kind == "fixed_tool",
        slot=frame.slot,
        name=frame.name,
        controller_symbol=frame.controller_symbol,
    )


def controller_text(
    fmt: ControllerFormat, *, frame: ServedFrame, version: Valued
) -> ControllerText:
    """{format, text, values} of a frame's version in a controller's own syntax."""
    export = export_frame(fmt, frame_data(frame, version))
    return ControllerText(format=export.format, text=export.text, values=export.values)
