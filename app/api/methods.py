"""GET /v1/methods: each method's poses, inputs, options and defaults, read off the registry."""

from __future__ import annotations

import typing

from fastapi import APIRouter
from pydantic import BaseModel, Field

from app.api.deps import ReadKey
from app.api.shared import all_formats
from app.kinematics.poses import POSE_FORMATS
from app.methods import METHODS
from app.methods.base import Listed, PosesRequired, RegisteredMethod
from app.methods.frame import FRAME_METHODS
from app.methods.frame.base import RegisteredFrameMethod
from app.methods.guided import GUIDED
from app.schemas.formats import FormatInfo
from app.words import FrameKind

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


class FrameRoleInfo(BaseModel):
    role: str = Field(description="a touch's `role`")
    words: str = Field(description="what the touch with this role touches")
    convention: str | None = Field(
        description="the options.convention these roles are taught under (null: the method "
        "has one set of roles)"
    )


class FrameMethodInfo(BaseModel):
    name: str = Field(description="the `method` of a frame calibration's body")
    description: str = Field(description="what the method computes from what it is given")
    kinds: list[FrameKind] = Field(description="the frame kinds the method calibrates")
    min_touches: int = Field(description="the fewest touches the method takes")
    max_touches: int = Field(description="the most touches the method takes")
    formats: list[str] = Field(description="the pose formats a touch's pose may be in")
    requires: list[str] = Field(description="the body's required fields but `method`")
    touch_fields: dict[str, bool] = Field(
        description="what a touch carries besides its pose, each field -> whether required"
    )
    roles: list[FrameRoleInfo] = Field(
        description="the roles a touch may take, with what each touches, by convention"
    )
    options: dict[str, dict[str, object]] = Field(
        description="each option: its default, whether required and its schema"
    )


class MethodList(BaseModel):
    items: list[MethodInfo]
    formats: list[FormatInfo]
    frame_methods: list[FrameMethodInfo] = Field(
        description="the methods of POST /v1/frames/{frame_id}/calibrations, with their roles"
    )


_COMMON = set(PosesRequired.model_fields) | {"options"}


def _options(method: Listed) -> dict[str, dict[str, object]]:
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


def _touch_fields(method: RegisteredFrameMethod) -> dict[str, bool]:
    field = method.request.model_fields.get("touches")
    if field is None:
        return {}
    (item,) = typing.get_args(field.annotation)  # list[TheTouch]
    return {name: f.is_required() for name, f in item.model_fields.items() if name != "pose"}


def describe_frame(method: RegisteredFrameMethod) -> FrameMethodInfo:
    """What a client needs to know to calibrate a frame with a method."""
    count = method.touch_count
    return FrameMethodInfo(
        name=method.name,
        description=method.description,
        kinds=list(method.kinds),
        min_touches=count.min,
        max_touches=count.max,
        formats=list(POSE_FORMATS),
        requires=[
            name
            for name, field in method.request.model_fields.items()
            if name != "method" and field.is_required()
        ],
        touch_fields=_touch_fields(method),
        roles=[
            FrameRoleInfo(role=role, words=words, convention=roles.convention)
            for roles in method.roles
            for role, words in roles.words.items()
        ],
        options=_options(method),
    )


@router.get("/v1/methods", response_model=MethodList)
def list_methods(key: ReadKey) -> MethodList:
    """Every calibration method: what it computes, how many poses it takes and in which
    formats, its required fields and its options with their defaults; and every pose format
    (as GET /v1/formats); and every frame calibration method with its touches' roles."""
    return MethodList(
        items=[describe(m) for m in METHODS],
        formats=all_formats(),
        frame_methods=[describe_frame(m) for m in FRAME_METHODS],
    )
