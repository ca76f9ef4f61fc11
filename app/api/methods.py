"""GET /v1/methods: each method's minimum poses, inputs, options and defaults."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from pydantic import BaseModel

from app.deps import ReadKey
from app.methods.catalog import describe_methods

router = APIRouter(tags=["stateless"])


class MethodInfo(BaseModel):
    name: str
    description: str
    min_poses: int
    available: bool
    requires: list[str]
    options: dict[str, Any]


class MethodList(BaseModel):
    items: list[MethodInfo]


@router.get("/v1/methods", response_model=MethodList)
def list_methods(key: ReadKey) -> object:
    return {"items": describe_methods()}
