"""POST /v1/solve's use case: a calibration's answer with nothing stored, in one call."""

from __future__ import annotations

from app.methods.base import MethodRequest
from app.schemas.results import SolveResult
from app.security.auth import Principal, transaction_for
from app.services import solve_pool
from app.services.calibrations import detached
from app.storage.db import loop_engine


async def solve_stateless(request: MethodRequest, *, actor: Principal) -> SolveResult:
    """Solve a /v1/solve body for `actor` (a stored robot of another cell is not found)."""
    # On the event loop, nothing awaited until the solve: a session is opened (on the loop's
    # held connection) only for a stored robot's model. The solve then runs in a solver
    # process (app.services.solve_pool) with no database connection held.
    if detached.stateless_robot_id(request) is None:
        kinematics = detached.stateless_kinematics(None, request)
    else:
        with transaction_for(actor, write=False, engine=loop_engine()) as session:
            kinematics = detached.stateless_kinematics(session, request)
    return await solve_pool.run(detached.solve_detached, request, kinematics)
