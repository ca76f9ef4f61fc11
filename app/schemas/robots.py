"""Robots: request and response bodies."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, BeforeValidator, Field, computed_field
from pydantic_core import PydanticCustomError

from app.kinematics.dh import MAX_LINK_DEG, MAX_LINK_MM
from app.kinematics.dh_table import Convention
from app.kinematics.urdf import MAX_URDF_CHARS
from app.schemas.common import FiniteFloat, Name, ShortText, StoredWord, StrictModel, Timestamp
from app.vendors.registry import PRESETS, vendor_pose_format
from app.words import PoseFormat

LinkMm = Annotated[FiniteFloat, Field(ge=-MAX_LINK_MM, le=MAX_LINK_MM)]
LinkDeg = Annotated[FiniteFloat, Field(ge=-MAX_LINK_DEG, le=MAX_LINK_DEG)]


class DHLinkIn(StrictModel):
    a: LinkMm = Field(description="link length, mm")
    alpha: LinkDeg = Field(description="link twist, deg")
    d: LinkMm = Field(description="link offset, mm")
    theta_offset: LinkDeg = Field(default=0.0, description="joint zero offset, deg")


class PresetKinematics(StrictModel):
    preset: Annotated[str, Field(examples=["ur5e"], json_schema_extra={"enum": sorted(PRESETS)})]


class DHKinematics(StrictModel):
    convention: Convention
    links: Annotated[list[DHLinkIn], Field(min_length=1, max_length=12)]


class UrdfKinematics(StrictModel):
    urdf: Annotated[str, Field(min_length=1, max_length=MAX_URDF_CHARS)] = Field(
        description="the robot's URDF document ('<robot ...>...</robot>'); lengths in metres, "
        "joint values of `joints` poses in radians unless `units` says degrees"
    )
    base_link: Annotated[str, Field(min_length=1, max_length=200)] | None = Field(
        default=None, description="the base frame's link (default: the URDF's root link)"
    )
    tip_link: Annotated[str, Field(min_length=1, max_length=200)] | None = Field(
        default=None,
        description="the flange link (default: the chain's last link, e.g. tool0)",
    )


_SHAPES = '{"convention": ..., "links": [...]} or {"urdf": "<robot ...>"}'


def _an_object(value: object) -> object:
    """A robot model is one of three objects: pydantic tried each on a bare name and said
    three times "Input should be a valid dictionary" at one loc (issue 51). Say instead
    which object to send: `{"preset": "tm5_900"}` for a preset's name."""
    if isinstance(value, dict | BaseModel):
        return value
    if isinstance(value, str) and value in PRESETS:
        send = f'{{"preset": "{value}"}}'
    else:
        send = f'{{"preset": NAME}} with NAME one of {", ".join(sorted(PRESETS))}; or {_SHAPES}'
    what = "a string" if isinstance(value, str) else type(value).__name__
    raise PydanticCustomError(
        "validation",
        "a robot model is an object, not {what}: send {send}",
        {"what": what, "send": send},
    )


Kinematics = Annotated[
    PresetKinematics | DHKinematics | UrdfKinematics, BeforeValidator(_an_object)
]


class RobotCreate(StrictModel):
    name: Name
    vendor: ShortText | None = None
    model: ShortText | None = None
    serial: ShortText | None = None
    cell: ShortText | None = None
    kinematics: Kinematics | None = None


class RobotUpdate(StrictModel):
    name: Name | None = None
    vendor: ShortText | None = None
    model: ShortText | None = None
    serial: ShortText | None = None
    cell: ShortText | None = None
    kinematics: Kinematics | None = None


class Robot(BaseModel):
    id: str
    name: str
    vendor: str | None
    model: str | None
    serial: str | None
    cell: str | None
    kinematics: dict[str, object] | None
    created_at: Timestamp
    updated_at: Timestamp

    @computed_field(  # type: ignore[prop-decorator]
        description="the pose format its maker's pendant shows a flange pose in, the maker "
        "found by its `vendor` (null when it names none this tcpcal knows): what its touches "
        "are typed in unless told otherwise (its controller's `pose_format` when it has one)"
    )
    @property
    def pose_format(self) -> StoredWord[PoseFormat] | None:
        return vendor_pose_format(self.vendor)
