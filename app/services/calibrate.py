"""Submitting a calibration: solve, grade, version, activate, store, all in one transaction.

Nothing is written before the solver succeeds, so unsolvable input (a 422) leaves no row.
The tool row is locked first (SELECT ... FOR UPDATE; BEGIN IMMEDIATE on SQLite), which
serialises version numbering and makes idempotency-key replays see the first response.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.auth import Principal
from app.errors import NotFound
from app.methods import run_method
from app.methods.base import SolvedTcp
from app.models import Calibration, IdempotencyRecord, Tool
from app.schemas.calibrations import Calibration as CalibrationOut
from app.services import audit, idempotency
from app.services.contexts import DbContext, StatelessContext
from app.services.kinematics import validate_kinematics
from app.services.pagination import paginate
from app.services.references import create_reference_point, ensure_reference_name_free
from app.services.registry import get_robot, get_tool
from app.services.tolerance import grade
from app.services.versions import IDENTITY_QUATERNION, activate, add_version
from app.solvers.errors import SolveError


# ---- results --------------------------------------------------------------------------------
def result_document(
    request: Any,
    solved: SolvedTcp,
    ctx: DbContext | StatelessContext,
) -> dict[str, Any]:
    """The CalibrationResult of a solve, graded against the tolerance in the context."""
    status, reasons = grade(solved.quality, ctx.tolerance, graded=solved.graded)
    quaternion = solved.quaternion
    warnings = list(solved.warnings) + reasons
    if quaternion is None:
        frame = ctx.active_frame()
        if frame is not None:
            quaternion = frame.quaternion
            warnings.append(
                f"orientation kept from active version {frame.version}: "
                f"{request.method} calibrates the position only"
            )
        else:
            quaternion = np.asarray(IDENTITY_QUATERNION)
    doc: dict[str, Any] = {
        "method": request.method,
        "algorithm": solved.algorithm,
        "status": status,
        "tcp": {
            "position_mm": [float(v) for v in solved.position_mm],
            "quaternion": [float(v) for v in quaternion],
        },
        "reference_point_mm": solved.reference_point_mm,
        "quality": solved.quality,
        "warnings": warnings,
        "details": {},
    }
    for key, value in solved.extra.items():
        doc[key] = value
    _refuse_non_finite(doc)
    return doc


def _refuse_non_finite(value: Any, path: tuple[str | int, ...] = ()) -> None:
    """The solvers promise finite results; should one not, the input did not determine the
    result: answer 422 before anything is stored, never store or send a NaN."""
    if isinstance(value, dict):
        for key, item in value.items():
            _refuse_non_finite(item, (*path, key))
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _refuse_non_finite(item, (*path, i))
    elif isinstance(value, float) and not math.isfinite(value):
        where = ".".join(str(p) for p in path)
        raise SolveError(
            "non-finite",
            f"the solution's {where} is not a finite number: these poses do not determine it",
            loc=path,
        )


def _calibration_out(row: Calibration, tool: Tool) -> dict[str, Any]:
    return {
        **row.result,
        "id": row.id,
        "tool_id": row.tool_id,
        "version": row.version,
        "active": row.version is not None and tool.active_version == row.version,
        "created_at": row.created_at,
        "created_by": row.created_by,
    }


# ---- use cases ------------------------------------------------------------------------------
def submit(
    session: Session,
    *,
    tool_id: str,
    request: Any,
    raw_body: dict[str, Any],
    idempotency_key: str | None,
    actor: Principal,
) -> tuple[dict[str, Any], bool]:
    """Solve and store a calibration; (Calibration document, replayed?)."""
    tool = get_tool(session, tool_id, for_update=True)
    fingerprint = idempotency.request_fingerprint(tool_id, raw_body)
    if idempotency_key is not None:
        replay = idempotency.replay(
            session, actor=actor, key=idempotency_key, fingerprint=fingerprint
        )
        if replay is not None:
            return replay, True

    robot = get_robot(session, tool.robot_id)
    point_name = _reference_point_to_save(request)
    if point_name is not None:
        ensure_reference_name_free(
            session,
            robot_id=robot.id,
            name=point_name,
            loc=("body", "options", "save_reference_point"),
        )
    ctx = DbContext(session, tool, robot)
    solved = run_method(request, ctx)  # SolveError -> 422 before anything is written
    doc = result_document(request, solved, ctx)
    if point_name is not None and doc["status"] != "accepted":
        doc["warnings"].append(
            f"reference point {point_name!r} not saved: the calibration is out of tolerance"
        )

    row = Calibration(
        tool_id=tool.id,
        method=request.method,
        algorithm=solved.algorithm,
        status=doc["status"],
        request=raw_body,
        result=doc,
        created_by=actor.name,
    )
    session.add(row)
    session.flush()
    version = add_version(
        session,
        tool=tool,
        position_mm=doc["tcp"]["position_mm"],
        quaternion=doc["tcp"]["quaternion"],
        source=request.method,
        status=doc["status"],
        calibration_id=row.id,
        note=request.note,
        actor=actor,
    )
    row.version = version.version
    should_activate = request.activate == "always" or (
        request.activate == "auto" and doc["status"] == "accepted"
    )
    if should_activate:
        activate(
            session,
            tool=tool,
            version=version.version,
            reason=f"calibration:{request.activate}",
            actor=actor,
        )
    if point_name is not None and doc["status"] == "accepted" and solved.reference_point_mm:
        create_reference_point(
            session,
            robot_id=tool.robot_id,
            name=point_name,
            position_mm=solved.reference_point_mm,
            covariance_mm2=solved.reference_covariance_mm2,
            source=request.method,
            calibration_id=row.id,
            actor=actor,
        )
    audit.record(
        session,
        actor=actor,
        action="calibration.create",
        resource_type="calibration",
        resource_id=row.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        details={
            "method": request.method,
            "status": doc["status"],
            "version": version.version,
            "activated": should_activate,
        },
    )
    out = _calibration_out(row, tool)
    if idempotency_key is not None:
        session.add(
            IdempotencyRecord(
                api_key_id=actor.key_id,
                key=idempotency_key,
                request_hash=fingerprint,
                status_code=201,
                response=CalibrationOut.model_validate(out).model_dump(mode="json"),
            )
        )
        session.flush()
    return out, False


def _reference_point_to_save(request: Any) -> str | None:
    name = getattr(getattr(request, "options", None), "save_reference_point", None)
    return str(name) if name is not None else None


def solve_stateless(session: Session, *, request: Any) -> dict[str, Any]:
    """Solve without storing anything (POST /v1/solve)."""
    kinematics: dict[str, Any] | None = None
    if request.kinematics is not None:
        kinematics = validate_kinematics(request.kinematics)
    elif request.robot_id is not None:
        kinematics = get_robot(session, request.robot_id).kinematics
    tolerance = request.tolerance.model_dump(exclude_unset=True) if request.tolerance else None
    ctx = StatelessContext(kinematics, tolerance)
    solved = run_method(request, ctx)
    doc = result_document(request, solved, ctx)
    if _reference_point_to_save(request) is not None:
        doc["warnings"].append("options.save_reference_point ignored: /v1/solve stores nothing")
    if request.activate != "auto":
        doc["warnings"].append(f"activate {request.activate!r} ignored: /v1/solve stores nothing")
    return doc


def list_calibrations(
    session: Session,
    *,
    tool_id: str,
    limit: int,
    cursor: str | None,
) -> tuple[list[dict[str, Any]], str | None]:
    """A tool's calibrations, oldest first."""
    tool = get_tool(session, tool_id)
    rows, next_cursor = paginate(
        session,
        select(Calibration).where(Calibration.tool_id == tool_id),
        created_col=Calibration.created_at,
        id_col=Calibration.id,
        limit=limit,
        cursor=cursor,
    )
    return [_calibration_out(r, tool) for r in rows], next_cursor


def get_calibration(session: Session, *, calibration_id: str) -> dict[str, Any]:
    """One calibration with the submission as received."""
    row = session.get(Calibration, calibration_id)
    if row is None:
        raise NotFound(f"no calibration with id {calibration_id}")
    tool = session.get(Tool, row.tool_id)
    assert tool is not None
    return {**_calibration_out(row, tool), "request": row.request}
