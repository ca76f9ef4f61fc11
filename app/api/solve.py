"""POST /v1/solve: a calibration's answer without storing anything."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Header, Request, Response

from app import solve_pool
from app.auth import act_for, authenticate_held
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
) -> Response:
    """Solve a calibration body without storing anything: the result a stored calibration would
    have, graded against the given (or default) tolerance; a unit or convention mix-up is
    refused with the reading that fits (`convention-mismatch`)."""
    # On the event loop, nothing awaited until the solve: the key is one statement on the
    # loop's held connection; a session is opened only for a stored robot's model. The solve
    # then runs in a solver process (app.solve_pool) with no database connection held.
    key = authenticate_held(loop_engine(), authorization, required="read")
    request.scope[KEY_NAME] = key.name
    if calibrate.stateless_robot_id(body) is None:
        kinematics = calibrate.stateless_kinematics(None, body)
    else:
        with session_scope(write=False, engine=loop_engine()) as session:
            act_for(session, key)  # a robot of another cell is not found
            kinematics = calibrate.stateless_kinematics(session, body)
    result = await solve_pool.run(calibrate.solve_detached, body, kinematics)
    # Built and validated in the solver process: serialised once, not validated again.
    return Response(result.model_dump_json(), media_type="application/json")
