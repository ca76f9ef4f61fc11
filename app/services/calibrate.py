"""Submitting a calibration: solve, grade, version, activate, store, all in one transaction.

The path is typed end to end: a request model (one per method, app.methods) -> the
method's run -> `Solved` -> one `CalibrationResult`, which is what is stored and served.
Nothing is written before the solver succeeds, so unsolvable input (a 422) leaves no row.
The tool row is locked first (SELECT ... FOR UPDATE; BEGIN IMMEDIATE on SQLite), which
serialises version numbering and makes idempotency-key replays see the first response.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple

import numpy as np
from sqlalchemy import Engine, and_, bindparam, insert, select
from sqlalchemy.orm import Session

from app.auth import Principal, act_for
from app.db import DriverWrite, HeldRead, engine_for, session_scope
from app.errors import InvalidInput, NotFound, located_in
from app.helpers.pagination import paginate
from app.helpers.tolerance import effective_tolerance, grade
from app.jsontypes import JsonArray, JsonObject
from app.logs import REQUEST_ID
from app.methods import method_of
from app.methods.base import FloatArray, MethodContext, MethodRequest, Solved, StoredPoint
from app.methods.npoint import NPointOptions
from app.metrics import SOLVE_SECONDS
from app.models import Calibration as CalibrationRow
from app.models import Robot, TcpVersion, Tool, new_id, table_of, utcnow
from app.schemas.calibrations import CALIBRATION_REQUESTS, StatelessFields
from app.schemas.common import Units
from app.schemas.results import (
    Calibration,
    CalibrationDetail,
    CalibrationResult,
    SolveResult,
    TouchGeometry,
)
from app.schemas.tools import Tcp
from app.services import audit, idempotency
from app.services.contexts import DbContext, SnapshotContext, StatelessContext
from app.services.diagnosis import EXPLAINABLE, Fit, implausible_flanges, refuse_mix_up
from app.services.frames import frame_from, parse_poses_with
from app.services.live import live_or_404, visible_tool
from app.services.references import create_reference_point, ensure_reference_name_free
from app.services.robots import get_robot, validate_kinematics
from app.services.tools import get_tool
from app.services.verdict import change_warning, held_for_change, summarise
from app.services.versions import (
    IDENTITY_QUATERNION,
    LockedTool,
    activate,
    add_version,
    lock_tool,
)
from app.solvers.quality import ellipsoid_semi_axes


# ---- solve and grade ------------------------------------------------------------------------
@dataclass(frozen=True)
class Outcome:
    """A graded result, and the point the touches met when the method finds one."""

    result: CalibrationResult
    touched_point: StoredPoint | None


def solve(request: MethodRequest, ctx: MethodContext) -> Outcome:
    """Run the request's method and grade its outcome against the context's tolerance;
    refuse a unit or convention mix-up (app.services.diagnosis) instead of grading it."""

    def attempt(fmt: str, units: Units) -> Fit:
        changed = request.model_copy(update={"format": fmt, "units": units})
        result = _solve_as_given(changed, ctx).result
        return Fit(result.quality.rms_mm or 0.0, result.status == "accepted")

    def positions(fmt: str, units: Units | None) -> FloatArray:
        return ctx.parse_poses(fmt, request.poses or [], units, loc=())[1]

    fmt, units = request.format, request.units
    try:
        outcome = _solve_as_given(request, ctx)
    except InvalidInput as refusal:
        if refusal.kind in EXPLAINABLE:
            near_base = implausible_flanges(positions, fmt, units)
            refuse_mix_up(fmt, units, attempt, positions, as_given=None, near_base=near_base)
        raise
    result = outcome.result
    near_base = implausible_flanges(positions, fmt, units)
    if result.status != "accepted" or near_base:
        as_given = Fit(result.quality.rms_mm or 0.0, good=False)
        refuse_mix_up(fmt, units, attempt, positions, as_given=as_given, near_base=near_base)
    return outcome


def _solve_as_given(request: MethodRequest, ctx: MethodContext) -> Outcome:
    with SOLVE_SECONDS.labels(request.method).time(), located_in("body"):
        solved = method_of(request).solve(request, ctx)
        return Outcome(graded_result(request.method, solved, ctx), solved.reference_point)


def graded_result(method: str, solved: Solved, ctx: MethodContext) -> CalibrationResult:
    """The result of a method's outcome: graded, orientation completed, compared with the
    active version, summed up in a sentence, every number finite."""
    tolerance = ctx.tolerance
    status, reasons = grade(solved.quality, tolerance, graded=solved.graded)
    previous = ctx.active_frame()
    quaternion = solved.quaternion
    if quaternion is None:  # a position-only method keeps the active orientation
        quaternion = previous.quaternion if previous else np.asarray(IDENTITY_QUATERNION)
    change = None
    if previous is not None:
        change = float(np.linalg.norm(solved.position_mm - previous.position_mm))
    held = held_for_change(change, tolerance)
    if held and change is not None and previous is not None:
        reasons.append(change_warning(change, previous, tolerance))
    point = solved.reference_point
    result = CalibrationResult(
        **solved.extras.model_dump(),
        method=method,
        algorithm=solved.algorithm,
        status=status,
        tcp=Tcp(
            position_mm=[float(v) for v in solved.position_mm],
            quaternion=[float(v) for v in quaternion],
        ),
        reference_point_mm=[float(v) for v in point.position_mm] if point else None,
        quality=solved.quality,
        warnings=[*solved.warnings, *reasons],
        change_from_active_mm=change,
    )
    result.summary = summarise(result, previous=previous, tolerance=tolerance, held=held)
    _refuse_non_finite(result.model_dump())  # python mode: a NaN stays a NaN
    return result


def _refuse_non_finite(doc: JsonObject) -> None:
    """The solvers promise finite results; should one not, the input did not determine the
    result: answer 422 before anything is stored, never store or send a NaN."""
    try:
        # json's C encoder meets every number in one pass (a walk in Python cost 5 % of a
        # calibration's solve); only a refused document is walked, to name the number.
        json.dumps(doc, allow_nan=False)
    except ValueError:
        _name_non_finite(doc)
        raise


def _name_non_finite(value: object, path: tuple[str | int, ...] = ()) -> None:
    """Raise the 422 that names the first non-finite number in `value`."""
    if isinstance(value, Mapping):
        for key, item in value.items():
            _name_non_finite(item, (*path, str(key)))
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _name_non_finite(item, (*path, i))
    elif isinstance(value, float) and not math.isfinite(value):
        where = ".".join(str(p) for p in path)
        raise InvalidInput(
            "non-finite",
            f"the solution's {where} is not a finite number: these poses do not determine it",
            loc=path,
        )


# ---- stored calibrations --------------------------------------------------------------------
def calibration_out(row: CalibrationRow, tool: Tool) -> Calibration:
    """A stored calibration as served."""
    return _served(
        CalibrationResult.model_validate(row.result),
        id=row.id,
        tool_id=row.tool_id,
        version=row.version,
        active_version=tool.active_version,
        created_at=row.created_at,
        created_by=row.created_by,
    )


def _served(
    result: CalibrationResult,
    *,
    id: str,
    tool_id: str,
    version: int | None,
    active_version: int | None,
    created_at: datetime,
    created_by: str,
) -> Calibration:
    # The result was validated when it was made (or read): the served document reuses its
    # fields as they are instead of validating them all again.
    return Calibration.model_construct(
        **dict(result),
        id=id,
        tool_id=tool_id,
        version=version,
        active=version is not None and active_version == version,
        created_at=created_at,
        created_by=created_by,
    )


def _reference_point_to_save(request: MethodRequest) -> str | None:
    options = getattr(request, "options", None)
    return options.save_reference_point if isinstance(options, NPointOptions) else None


@dataclass(frozen=True)
class Snapshot:
    """What a calibration's solve reads from the database: equal snapshots, equal results."""

    tolerance: JsonObject | None
    active_version: int | None
    kinematics: JsonObject | None


@dataclass(frozen=True)
class Presolved:
    """A calibration solved before its transaction, with what the solve read."""

    snapshot: Snapshot
    outcome: Outcome


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


class SnapshotRow(NamedTuple):
    """A row of SNAPSHOT_READ: the tool, its robot's model and cell, and its active version
    with its calibration's result (None when it has no active version, or the version no
    calibration)."""

    name: str
    archived_at: datetime | None
    tolerance: JsonObject
    active_version: int | None
    kinematics: JsonObject | None
    cell: str | None
    version: int | None
    position_mm: JsonArray | None
    quaternion: JsonArray | None
    result: JsonObject | None


_TOOL, _ROBOT = table_of(Tool), table_of(Robot)
_VERSION, _CALIBRATION = table_of(TcpVersion), table_of(CalibrationRow)
#: What a calibration's solve reads, as one statement on the event loop's held connection
#: (app.db.HeldRead): the tool, its robot's model, its active version and the covariance
#: its calibration reported. Read in a worker thread through a session, the same took three
#: ORM queries and a thread hop (2 ms of the server's one core per calibration).
SNAPSHOT_READ = HeldRead(
    SnapshotRow,
    select(
        _TOOL.c.name,
        _TOOL.c.archived_at,
        _TOOL.c.tolerance,
        _TOOL.c.active_version,
        _ROBOT.c.kinematics,
        _ROBOT.c.cell,
        _VERSION.c.version,
        _VERSION.c.position_mm,
        _VERSION.c.quaternion,
        _CALIBRATION.c.result,
    )
    .select_from(_TOOL)
    .join(_ROBOT, _ROBOT.c.id == _TOOL.c.robot_id)
    .outerjoin(
        _VERSION,
        and_(_VERSION.c.tool_id == _TOOL.c.id, _VERSION.c.version == _TOOL.c.active_version),
    )
    .outerjoin(_CALIBRATION, _CALIBRATION.c.id == _VERSION.c.calibration_id)
    .where(_TOOL.c.id == bindparam("tool_id")),
)


def snapshot_held(
    engine: Engine, tool_id: str, actor: Principal | None = None
) -> tuple[Snapshot, SnapshotContext]:
    """What a calibration of this tool will solve against (no lock, no session): the
    snapshot the write compares under the lock, and the solver's context. A tool of a robot
    outside the actor's cells is not found."""
    row = SNAPSHOT_READ.one_or_none(engine, tool_id=tool_id)
    if row is not None and actor is not None and not actor.sees_cell(row.cell):
        row = None
    row = live_or_404(row, "tool", tool_id)
    frame = None
    if row.version is not None:  # a version's columns are never NULL
        assert row.position_mm is not None
        assert row.quaternion is not None
        frame = frame_from(row.position_mm, row.quaternion, row.version, row.result)
    snapshot = Snapshot(row.tolerance, row.active_version, row.kinematics)
    return snapshot, SnapshotContext(row.kinematics, effective_tolerance(row.tolerance), frame)


def solve_snapshot(request: MethodRequest, ctx: SnapshotContext) -> Outcome | None:
    """Solve against a snapshot (in a solver process); None when the method needs to look
    up more stored data (reference points, other tools, laser devices): solve it in place."""
    try:
        return solve(request, ctx)
    except InvalidInput as refusal:
        if refusal.kind == "needs-storage":
            return None
        raise


@dataclass(frozen=True)
class Submitted:
    """A stored (or replayed) calibration as served, and what the metrics count of it."""

    body: str  # the Calibration, as JSON
    replayed: bool
    method: str
    status: str


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
    in a write transaction of its own. One call for a solver process (app.solve_pool), which
    writes to `database_url` itself: the result never travels back to be stored, and the
    write costs the server's event loop nothing. Its audit events carry `request_id`."""
    token = REQUEST_ID.set(request_id)
    try:
        outcome = solve_snapshot(request, ctx)
        with session_scope(write=True, engine=engine_for(database_url)) as session:
            act_for(session, actor)
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

    point_name = _reference_point_to_save(request)
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
    method: str,
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


_INSERT_CALIBRATION = DriverWrite(insert(_CALIBRATION))


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
        tool=tool,
        position_mm=result.tcp.position_mm,
        quaternion=result.tcp.quaternion,
        source=request.method,
        status=result.status,
        calibration_id=calibration_id,
        note=request.note,
        actor=actor,
        created_at=now,
    )
    return _served(
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
    due = request.activate == "always" or (
        request.activate == "auto"
        and result.status == "accepted"
        and not held_for_change(result.change_from_active_mm, tolerance)
    )
    if due:
        activate(
            session,
            tool=tool,
            version=tool.last_version,
            reason=f"calibration:{request.activate}",
            actor=actor,
        )
    return due


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
    """Solve a /v1/solve body with nothing stored (runs in a solver process: app.solve_pool)."""
    assert isinstance(request, StatelessFields)
    result = solve(request, StatelessContext(kinematics, request.tolerance)).result
    if _reference_point_to_save(request) is not None:
        result.warnings.append("options.save_reference_point ignored: /v1/solve stores nothing")
    if request.activate != "auto":
        result.warnings.append(f"activate {request.activate!r} ignored: /v1/solve stores nothing")
    return SolveResult.model_construct(**dict(result))  # validated when it was made


def list_calibrations(
    session: Session, *, tool_id: str, limit: int, cursor: str | None
) -> tuple[list[Calibration], str | None]:
    """A tool's calibrations, oldest first."""
    tool = get_tool(session, tool_id)
    rows, next_cursor = paginate(
        session,
        select(CalibrationRow).where(CalibrationRow.tool_id == tool_id),
        created_col=CalibrationRow.created_at,
        id_col=CalibrationRow.id,
        limit=limit,
        cursor=cursor,
    )
    return [calibration_out(r, tool) for r in rows], next_cursor


def get_calibration(session: Session, *, calibration_id: str) -> CalibrationDetail:
    """One calibration with the submission as received."""
    row = session.get(CalibrationRow, calibration_id)
    tool = None if row is None else visible_tool(session, row.tool_id)
    if row is None or tool is None:  # a tool of another cell's robot: as if absent
        raise NotFound(f"no calibration with id {calibration_id}")
    out = calibration_out(row, tool)
    return CalibrationDetail(
        **out.model_dump(), request=row.request, geometry=_geometry(session, row, tool, out)
    )


def _geometry(
    session: Session, row: CalibrationRow, tool: Tool, out: Calibration
) -> TouchGeometry | None:
    """The touches of a stored submission in space, read again from the request."""
    request = CALIBRATION_REQUESTS.validate_python(row.request)
    if not request.poses or request.format is None:
        return None
    robot = get_robot(session, tool.robot_id)
    try:
        rotations, flanges = parse_poses_with(
            robot.kinematics, request.format, request.poses, request.units, loc=()
        )
    except InvalidInput:  # the robot's kinematics changed since: no picture, the rest stands
        return None
    tips = flanges + rotations @ np.asarray(out.tcp.position_mm)
    geometry = TouchGeometry(flange_positions_mm=flanges.tolist(), tip_positions_mm=tips.tolist())
    quality = out.quality
    if quality.tcp_covariance_mm2 is not None and quality.ellipsoid95_scale is not None:
        semi, axes = ellipsoid_semi_axes(quality.tcp_covariance_mm2, quality.ellipsoid95_scale)
        geometry.ellipsoid95_semi_axes_mm, geometry.ellipsoid95_axes = semi.tolist(), axes.tolist()
    return geometry
