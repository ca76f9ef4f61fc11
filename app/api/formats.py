"""GET /v1/formats: every pose format's numbers in order, default units and rotation."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.deps import ReadKey
from app.api.shared import all_formats
from app.schemas.formats import FormatList
from app.vendors.registry import FILE_KINDS, TOOL_NUMBERS

router = APIRouter(tags=["stateless"])


@router.get("/v1/formats", response_model=FormatList)
def list_formats(key: ReadKey) -> FormatList:
    """Every pose format: the names of its numbers in order, its default units (overridden
    by a request's `units`) and how its numbers make the rotation."""
    return FormatList(
        items=all_formats(), controller_files=dict(FILE_KINDS), tool_numbers=dict(TOOL_NUMBERS)
    )
