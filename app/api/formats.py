"""GET /v1/formats: every pose format's numbers in order, default units and rotation."""

from __future__ import annotations

from fastapi import APIRouter

from app.deps import ReadKey
from app.exports import FILE_KINDS
from app.kinematics.poses import (
    POSE_FORMATS,
    ROTATION_CONVENTIONS,
    default_units,
    format_components,
)
from app.schemas.common import Units
from app.schemas.formats import FormatInfo, FormatList
from app.tool_numbers import TOOL_NUMBERS

router = APIRouter(tags=["stateless"])


def describe_format(fmt: str) -> FormatInfo:
    """One format as clients read it, from the definitions in app.kinematics.poses."""
    components = format_components(fmt)
    units = default_units(fmt)
    return FormatInfo(
        name=fmt,
        components=list(components),
        arity=None if fmt == "joints" else len(components),
        default_units=Units(length=units.length, angle=units.angle),
        rotation=ROTATION_CONVENTIONS[fmt],
    )


def all_formats() -> list[FormatInfo]:
    return [describe_format(fmt) for fmt in POSE_FORMATS]


@router.get("/v1/formats", response_model=FormatList)
def list_formats(key: ReadKey) -> FormatList:
    """Every pose format: the names of its numbers in order, its default units (overridden
    by a request's `units`) and how its numbers make the rotation."""
    return FormatList(
        items=all_formats(), controller_files=dict(FILE_KINDS), tool_numbers=dict(TOOL_NUMBERS)
    )
