"""What GET /v1/methods tells a client: each method's inputs, minimum poses and option
defaults, read off the request schemas themselves so the two can never disagree."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from app.methods import RUNNERS
from app.schemas import calibrations as c

#: (request model, minimum poses, one-line description)
CATALOG: dict[str, tuple[type[BaseModel], int, str]] = {
    "xyz_npoint": (
        c.XyzNpointCalibration,
        4,
        "N >= 4 touches of one fixed point from different orientations -> TCP "
        "position and the point (lecture: XYZ 4-point)",
    ),
    "xyz_reference": (
        c.XyzReferenceCalibration,
        1,
        "one touch of a known point -> TCP position (lecture: XYZ reference)",
    ),
    "tcp_z_x": (
        c.TcpZxCalibration,
        4,
        "N-point touches plus pure translations along tool +-Z (and X) -> full frame "
        "(ABB TCP&Z,X; Fanuc six-point)",
    ),
    "abc_2point": (
        c.Abc2PointCalibration,
        3,
        "TCP touch, a point behind it on the working axis, a point on +Y -> "
        "orientation (KUKA ABC 2-point)",
    ),
    "abc_world": (
        c.AbcWorldCalibration,
        1,
        "one pose with the tool aligned to base axes -> orientation (KUKA ABC world 5D/6D)",
    ),
    "laser_beam": (
        c.LaserBeamCalibration,
        1,
        "beam break/restore sweeps at two or more heights and a final descent -> "
        "tool axis, runout, offset, length",
    ),
    "manual": (c.ManualCalibration, 0, "a TCP entered by hand, as numbers or as one pose"),
}

_COMMON = {"method", "format", "poses", "units", "activate", "note", "options"}


def _options(model: type[BaseModel]) -> dict[str, Any]:
    annotation = model.model_fields["options"].annotation
    if not (isinstance(annotation, type) and issubclass(annotation, BaseModel)):
        return {}
    out: dict[str, Any] = {}
    for name, field in annotation.model_fields.items():
        out[name] = {
            "default": None
            if field.is_required()
            else field.get_default(call_default_factory=True),
            "required": field.is_required(),
            "schema": annotation.model_json_schema()["properties"][name],
        }
    return out


def describe_methods() -> list[dict[str, Any]]:
    """Every method with its inputs and defaults."""
    items = []
    for name, (model, min_poses, description) in CATALOG.items():
        extra = [
            f for f, info in model.model_fields.items() if f not in _COMMON and info.is_required()
        ]
        items.append(
            {
                "name": name,
                "description": description,
                "min_poses": min_poses,
                "available": name in RUNNERS,
                "requires": extra,
                "options": _options(model),
            }
        )
    return items
