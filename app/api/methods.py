"""GET /v1/methods: each method's poses, inputs, options and defaults, read off the registry."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from app.api.deps import ReadKey
from app.api.shared import all_formats
from app.kinematics.poses import POSE_FORMATS
from app.methods import METHODS
from app.methods.base import PosesRequired, RegisteredMethod
from app.methods.guided import GUIDED
from app.schemas.formats import FormatInfo

router = APIRouter(tags=["stateless"])


class MethodInfo(BaseModel):
    name: str
    description: str
    min_poses: int
    max_poses: int
    formats: list[str]
    requires: list[str]
    options: dict[str, dict[str, object]]
    guided: bool = Field(
        description="a guided session (POST /v1/tools/{tool_id}/sessions) collects its touches: "
        "the method a client calibrates with unless told otherwise"
    )


class MethodList(BaseModel):
    items: list[MethodInfo]
    formats: list[FormatInfo]


_COMMON = set(PosesRequired.model_fields) | {"options"}


def _options(method: RegisteredMethod) -> dict[str, dict[str, object]]:
    model = method.options
    if model is None:
        return {}
    properties = model.model_json_schema()["properties"]
    return {
        name: {
            "default": None
            if field.is_required()
            else field.get_default(call_default_factory=True),
            "required": field.is_required(),
            "schema": properties[name],
        }
        for name, field in model.model_fields.items()
    }


def describe(method: RegisteredMethod) -> MethodInfo:
    """What a client needs to know to call a method."""
    count = method.pose_count
    return MethodInfo(
        name=method.name,
        description=method.description,
        min_poses=count.min,
        max_poses=count.max,
        formats=list(POSE_FORMATS) if issubclass(method.request, PosesRequired) else [],
        requires=[
            name
            for name, field in method.request.model_fields.items()
            if name not in _COMMON and field.is_required()
        ],
        options=_options(method),
        guided=method is GUIDED,
    )


@router.get("/v1/methods", response_model=MethodList)
def list_methods(key: ReadKey) -> MethodList:
    """Every calibration method: what it computes, how many poses it takes and in which
    formats, its required fields and its options with their defaults; and every pose format
    (as GET /v1/formats)."""
    return MethodList(items=[describe(m) for m in METHODS], formats=all_formats())
