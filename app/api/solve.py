"""POST /v1/solve: a calibration's answer without storing anything."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body

from app.deps import ReadKey, SessionDep
from app.methods import openapi_examples
from app.schemas.calibrations import SolveRequest
from app.schemas.results import SolveResult
from app.services import calibrate

router = APIRouter(tags=["stateless"])


@router.post("/v1/solve", response_model=SolveResult)
def solve(
    body: Annotated[SolveRequest, Body(openapi_examples=openapi_examples())],
    session: SessionDep,
    key: ReadKey,
) -> SolveResult:
    """Solve a calibration body without storing anything: the result a stored calibration would
    have, graded against the given (or default) tolerance; a unit or convention mix-up is
    refused with the reading that fits (`convention-mismatch`)."""
    return calibrate.solve_stateless(session, request=body)
