"""What a client needs to know of each pose format: its numbers, units and rotation."""

from __future__ import annotations

from pydantic import BaseModel, Field

from app.schemas.common import Units
from app.words import CONTROLLER_FORMATS, ControllerFormat


class FormatInfo(BaseModel):
    name: str
    components: list[str] = Field(
        description="the names of one pose's numbers in order (joints: q1 .. qn, one per joint)"
    )
    arity: int | None = Field(description="numbers per pose; null for joints (the robot's axes)")
    default_units: Units = Field(description="units used unless the request's `units` overrides")
    rotation: str = Field(description="how the numbers make the flange orientation")


class FormatList(BaseModel):
    items: list[FormatInfo]
    controllers: list[ControllerFormat] = Field(
        default_factory=lambda: list(CONTROLLER_FORMATS),
        description="the controller text formats of GET /v1/tools/{id}/tcp?format=",
    )
    controller_files: dict[str, str] = Field(
        default_factory=dict,
        description="what each controller format's file is (GET /v1/tools/{id}/tcp?format= "
        'with Accept: text/plain), e.g. {"abb": "RAPID module"}',
    )
    tool_numbers: dict[str, tuple[int, int]] = Field(
        default_factory=dict,
        description="the controller formats whose file addresses a tool by its number (the "
        'tool\'s slot), and the first and last number, e.g. {"fanuc": [1, 10]}: a tool '
        "without a slot has no such file",
    )
