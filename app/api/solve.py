"""POST /v1/solve: a calibration's answer without storing anything."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Response

from app.api.deps import HeldReadKey
from app.methods import openapi_examples
from app.methods.requests import SolveRequest
from app.schemas.results import SolveResult
from app.services.calibrations import stateless

router = APIRouter(tags=["stateless"])


@router.post("/v1/solve", response_model=SolveResult)
async def solve(
    body: Annotated[SolveRequest, Body(openapi_examples=openapi_examples())],
    key: HeldReadKey,
) -> Response:
    """Solve a calibration body without storing anything: the result a stored calibration would
    have, graded against the given (or default) tolerance; a unit or convention mix-up is
    refused with the reading that fits (`convention-mismatch`)."""
    result = await stateless.solve_stateless(body, actor=key)
    # Built and validated in the solver process: serialised once, not validated again.
    return Response(result.model_dump_json(), media_type="application/json")
