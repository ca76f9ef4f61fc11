"""Storing a calibration: the tool locked, the result solved (or the presolved one kept),
versioned, activated when due, audited and remembered for idempotent replays, in one write
transaction (`submit`); `solve_and_submit` is the one call a solver process makes."""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import insert
from sqlalchemy.orm import Session

from app.helpers.tolerance import effective_tolerance
from app.jsontypes import JsonObject
from app.logs import REQUEST_ID
from app.methods.base import MethodRequest, StoredPoint
from app.schemas.results import (
    Calibration,
    CalibrationResult,
)
from app.security.auth import Principal, transaction_for
from app.services import idempotency
from app.services.audit import writes as audit
from app.services.calibrations.contexts import DbContext, SnapshotContext
from app.services.calibrations.grading import reference_point_to_save, solve
from app.services.calibrations.presolve import Presolved, Snapshot, solve_snapshot
from app.services.calibrations.stored import served
from app.services.lifecycle.activation import activation_due
from app.services.lifecycle.versions import activate, add_version
from app.services.references.references import create_reference_point, ensure_reference_name_free
from app.services.robots.robots import get_robot
from app.services.tools.subject import TOOL
from app.services.tools.tools import get_tool
from app.services.tools.versions import LockedTool, lock_tool, save_deferred
from app.storage.db import DriverWrite, engine_for
from app.storage.models import Calibration as CalibrationRow
from app.storage.models import new_id, table_of, utcnow
from app.words import MethodName, Status


def replayed(
    session: Session,
    tool_id: str,
    raw_body: JsonObject,
    idempotency_key: str | None,
    actor: Principal,
    *,
    purge: bool = False,
) -> Calibration | None:
    """The first response to this key and body, if there was one (409 for another body).
    `purge`: also delete expired records (inside a write transaction only)."""
    if idempotency_key is None:
        return None
    fingerprint = idempotency.request_fingerprint(tool_id, raw_body)
    replay = idempotency.replay(
        session, actor=actor, key=idempotency_key, fingerprint=fingerprint, purge=purge
    )
    return None if replay is None else Calibration.model_validate(replay)


_INSERT_CALIBRATION = DriverWrite(insert(table_of(CalibrationRow)))


@dataclass(frozen=True)
class Submitted:
    """A stored (or replayed) calibration as served, and what the metrics count of it."""

    body: str  # the Calibration, as JSON
    replayed: bool
    method: MethodName
    status: Status


def solve_and_submit(
    database_url: str,
    *,
    tool_id: str,
    request: MethodRequest,
    snapshot: Snapshot,
    ctx: SnapshotContext,
    raw_body: JsonObject,
    idempotency_key: str | None,
    actor: Principal,
    request_id: str | None,
) -> Submitted:
    """A calibration from its snapshot on: the solve, with no transaction open, then `submit`
    in a write transaction of its own. One call for a solver process (app.services.solve_pool),
    which writes to `database_url` itself: the result never travels back to be stored, and the
    write costs the server's event loop nothing. Its audit events carry `request_id`."""
    token = REQUEST_ID.set(request_id)
    try:
        outcome = solve_snapshot(request, ctx)
        with transaction_for(actor, write=True, engine=engine_for(database_url)) as session:
            doc, replayed = submit(
                session,
                tool_id=tool_id,
                request=request,
                raw_body=raw_body,
                idempotency_key=idempotency_key,
                actor=actor,
                solved=None if outcome is None else Presolved(snapshot, outcome),
            )
    finally:
        REQUEST_ID.reset(token)
    return Submitted(doc.model_dump_json(), replayed, doc.method, doc.status)


def submit(
    session: Session,
    *,
    tool_id: str,
    request: MethodRequest,
    raw_body: JsonObject,
    idempotency_key: str | None,
    actor: Principal,
    solved: Presolved | None = None,
) -> tuple[Calibration, bool]:
    """Solve and store a calibration; (the stored Calibration, replayed?). With `solved` (from
    `solve_snapshot`, made before the lock) the stored result is that one, unless what it
    read has changed since."""
    tool = lock_tool(session, tool_id)
    replay = replayed(session, tool_id, raw_body, idempotency_key, actor, purge=True)
    if replay is not None:
        return replay, True

    point_name = reference_point_to_save(request)
    if point_name is not None:
        ensure_reference_name_free(
            session,
            robot_id=tool.robot_id,
            name=point_name,
            loc=("body", "options", "save_reference_point"),
        )
    now = Snapshot(tool.tolerance, tool.active_version, tool.kinematics)
    if solved is None or solved.snapshot != now:
        # Solved here under the tool's lock: nothing was solved beforehand, or the tool's
        # tolerance, active version or robot model changed since (the result would differ).
        ctx = DbContext(session, get_tool(session, tool_id), get_robot(session, tool.robot_id))
        outcome = solve(request, ctx)
    else:
        outcome = solved.outcome
    result, point = outcome.result, outcome.touched_point
    keep_point = point_name is not None and result.status == "accepted"
    if point_name is not None and not keep_point:
        result.warnings.append(
            f"reference point {point_name!r} not saved: the calibration is out of tolerance"
        )

    out = _store(session, tool=tool, request=request, raw_body=raw_body, result=result, actor=actor)
    if _activate_if_due(session, tool=tool, request=request, result=result, actor=actor):
        out.active = True
    save_deferred(session, tool)  # the counters and the drift, once for both writes
    if keep_point and point_name is not None and point is not None:
        _save_touched_point(session, tool, point_name, point, request.method, out.id, actor)
    audit.record(
        session,
        actor=actor,
        action="calibration.create",
        resource_type="calibration",
        resource_id=out.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        version=out.version,
        details={
            "method": request.method,
            "status": result.status,
            "activated": out.active,
            "note": request.note,
            "summary": result.summary,
        },
    )
    if idempotency_key is not None:
        idempotency.remember(
            session,
            actor=actor,
            key=idempotency_key,
            fingerprint=idempotency.request_fingerprint(tool_id, raw_body),
            response=out.model_dump(mode="json"),
        )
    return out, False


def _save_touched_point(
    session: Session,
    tool: LockedTool,
    name: str,
    point: StoredPoint,
    method: MethodName,
    calibration_id: str,
    actor: Principal,
) -> None:
    """Register the point the touches met as a named reference point of the tool's robot."""
    create_reference_point(
        session,
        robot_id=tool.robot_id,
        name=name,
        position_mm=point.position_mm.tolist(),
        covariance_mm2=None if point.covariance_mm2 is None else point.covariance_mm2.tolist(),
        source=method,
        calibration_id=calibration_id,
        actor=actor,
    )


def _store(
    session: Session,
    *,
    tool: LockedTool,
    request: MethodRequest,
    raw_body: JsonObject,
    result: CalibrationResult,
    actor: Principal,
) -> Calibration:
    """The calibration row and the tool's next version (every result is versioned), as served
    (not yet active: see _activate_if_due)."""
    # The calibration goes in first (the version references it), numbered and timed as the
    # version that add_version makes next.
    calibration_id, version, now = new_id(), tool.next_version, utcnow()
    _INSERT_CALIBRATION.execute(
        session,
        [
            {
                "id": calibration_id,
                "tool_id": tool.id,
                "method": request.method,
                "algorithm": result.algorithm,
                "status": result.status,
                "request": raw_body,
                "result": result.model_dump(mode="json"),
                "version": version,
                "created_at": now,
                "created_by": actor.name,
            }
        ],
    )
    add_version(
        session,
        TOOL,
        locked=tool,
        position_mm=result.tcp.position_mm,
        quaternion=result.tcp.quaternion,
        source=request.method,
        status=result.status,
        calibration_id=calibration_id,
        note=request.note,
        actor=actor,
        created_at=now,
        deferred=True,  # saved by submit, with any activation of the version
    )
    return served(
        result,
        id=calibration_id,
        tool_id=tool.id,
        version=version,
        active_version=tool.active_version,
        created_at=now,
        created_by=actor.name,
    )


def _activate_if_due(
    session: Session,
    *,
    tool: LockedTool,
    request: MethodRequest,
    result: CalibrationResult,
    actor: Principal,
) -> bool:
    """Activate the new version as `activate` asks ("auto": only within tolerance and not
    too far from the active version)."""
    tolerance = effective_tolerance(tool.tolerance)
    kind = activation_due(request.activate, result.status, result.change_from_active_mm, tolerance)
    if kind is not None:
        activate(
            session,
            TOOL,
            locked=tool,
            version=tool.last_version,
            reason=kind,
            actor=actor,
            deferred=True,  # saved by submit with the version's
        )
    return kind is not None
