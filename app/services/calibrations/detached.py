"""POST /v1/solve: a calibration request solved with nothing stored."""

from __future__ import annotations

from sqlalchemy.orm import Session

from app.jsontypes import JsonObject
from app.methods.base import MethodRequest
from app.methods.requests import StatelessFields
from app.schemas.results import (
    SolveResult,
)
from app.services.calibrations.contexts import StatelessContext
from app.services.calibrations.grading import reference_point_to_save, solve
from app.services.robots.robots import get_robot, validate_kinematics


def stateless_robot_id(request: MethodRequest) -> str | None:
    """The stored robot whose model a /v1/solve body uses (None: inline or no model)."""
    assert isinstance(request, StatelessFields)  # the /v1/solve union's models all are
    return request.robot_id if request.kinematics is None else None


def stateless_kinematics(session: Session | None, request: MethodRequest) -> JsonObject | None:
    """The robot model a /v1/solve body uses: given inline, or a stored robot's (`session`
    is needed only when `stateless_robot_id` names one)."""
    assert isinstance(request, StatelessFields)
    if request.kinematics is not None:
        return validate_kinematics(request.kinematics)
    if request.robot_id is not None:
        assert session is not None
        return get_robot(session, request.robot_id).kinematics
    return None


def solve_detached(request: MethodRequest, kinematics: JsonObject | None) -> SolveResult:
    """Solve a /v1/solve body with nothing stored (runs in a solver process:
    app.services.solve_pool)."""
    assert isinstance(request, StatelessFields)
    result = solve(request, StatelessContext(kinematics, request.tolerance)).result
    if reference_point_to_save(request) is not None:
        result.warnings.append("options.save_reference_point ignored: /v1/solve stores nothing")
    if request.activate != "auto":
        result.warnings.append(f"activate {request.activate!r} ignored: /v1/solve stores nothing")
    return SolveResult.model_construct(**dict(result))  # validated when it was made
