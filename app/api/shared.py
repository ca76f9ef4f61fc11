"""What several routers share besides request parameters (those are app.api.params): the
page a list route answers, the body as received, the controller failures a route documents
and the pose formats. Here so that no router imports another (an import contract)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

from fastapi import Request
from pydantic import BaseModel

from app.errors import InvalidInput
from app.jsontypes import JsonObject
from app.kinematics.poses import (
    POSE_FORMATS,
    ROTATION_CONVENTIONS,
    default_units,
    format_components,
)
from app.schemas.common import Page, Units
from app.schemas.formats import FormatInfo
from app.vendors.registry import MAKERS

M = TypeVar("M", bound=BaseModel)

#: The failures of a route that reads the robot's controller, as its OpenAPI `responses`.
CONTROLLER_FAILURES: dict[int | str, dict[str, object]] = {
    409: {
        "description": "`/robot-moving`: two reads 100 ms apart differ by more than 0.01 mm "
        "or 0.01 deg (nothing kept); `/no-controller` (a touch of a robot without one)"
    },
    404: {"description": "`/no-controller`: a pose read of a robot without one"},
    502: {
        "description": "`/controller-unreachable` within the controller's timeout_s, or "
        "`/controller-refused` with the controller's own words in `controller_message`"
    },
}


def page(model: type[M], items: Sequence[object], next_cursor: str | None) -> Page[M]:
    """A list route's answer: one page of `model`s, read from stored rows by attribute (or
    from models as they are)."""
    paged: type[Page[M]] = Page[model]  # type: ignore[valid-type]
    return paged.model_validate({"items": items, "next_cursor": next_cursor}, from_attributes=True)


async def raw_json_body(request: Request) -> JsonObject:
    """The body as received, before validation: the JSON FastAPI parsed to validate it, which
    the request keeps (parsing the bytes again cost 30 us of the event loop per calibration)."""
    parsed = await request.json()
    if not isinstance(parsed, dict):
        raise InvalidInput("validation", "the body must be a JSON object", loc=("body",))
    return parsed


def describe_format(fmt: str) -> FormatInfo:
    """One format as clients read it, from the definitions in app.kinematics.poses."""
    components = format_components(fmt)
    units = default_units(fmt)
    return FormatInfo(
        name=fmt,
        components=list(components),
        arity=None if fmt == "joints" else len(components),
        default_units=Units(length=units.length, angle=units.angle),
        rotation=ROTATION_CONVENTIONS[fmt] + _shown_by(fmt),
    )


def _shown_by(fmt: str) -> str:
    """Which makers' pendants show a flange pose in the format (their Maker.pose_format)."""
    names = [maker.name for maker in MAKERS if maker.pose_format == fmt]
    return f"; the pose format of the {' and '.join(names)} pendant" if names else ""


def all_formats() -> list[FormatInfo]:
    return [describe_format(fmt) for fmt in POSE_FORMATS]
