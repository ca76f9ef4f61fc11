"""POST /v1/solve: a calibration's answer without storing anything."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Header, Request

from app import solve_pool
from app.auth import authenticate
from app.db import loop_engine, session_scope
from app.methods import openapi_examples
from app.middleware import KEY_NAME
from app.schemas.calibrations import SolveRequest
from app.schemas.results import SolveResult
from app.services import calibrate

router = APIRouter(tags=["stateless"])


@router.post("/v1/solve", response_model=SolveResult)
async def solve(
    body: Annotated[SolveRequest, Body(openapi_examples=openapi_examples())],
    request: Request,
    authorization: Annotated[str | None, Header(include_in_schema=False)] = None,
) -> SolveResult:
    """Solve a calibration body without storing anything: the result a stored calibration would
    have, graded against the given (or default) tolerance; a unit or convention mix-up is
    refused with the reading that fits (`convention-mismatch`)."""
    # The key and the robot model are read first in a short transaction; the solve then runs
    # in a solver process (app.solve_pool) with no database connection held.
    with session_scope(write=False, engine=loop_engine()) as session:
        key = authenticate(session, authorization, required="read")
        kinematics = calibrate.stateless_kinematics(session, body)
    request.scope[KEY_NAME] = key.name
    return await solve_pool.run(calibrate.solve_detached, body, kinematics)
