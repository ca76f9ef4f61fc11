"""Planning touch sets and guided sessions: calibrate touch by touch, stop when it is enough.

A session stores its settings and the touches kept so far; the estimate, the outliers, the
next suggested pose and `done` are computed from them on every read, with the same N-point
solve and grading a calibration gets (app.services.calibrations.grading.solve). So a session
survives a restart and any worker or instance continues it; writes lock the session row.

The first touch is the centre of the reachable cone (its tool axis, its spin). The next pose
is the touch within the cone that most reduces the largest remaining TCP variance
(app.solvers.planning.next_touch), placed so that the current TCP estimate lands on the
current estimate of the point. A touch the robust fit sets aside is named once there are 5
touches (with 4 every touch is needed to solve; a miss cannot be told apart).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.arrays import FloatArray
from app.errors import Conflict, InvalidInput, NotFound
from app.helpers.pagination import paginate
from app.helpers.tolerance import effective_tolerance
from app.jsontypes import JsonObject
from app.kinematics.poses import one_pose, pose_to_format
from app.kinematics.touchsets import cone_rotations, flange_positions
from app.methods.base import MethodRequest
from app.methods.guided import SessionCreate
from app.methods.requests import CALIBRATION_REQUESTS
from app.schemas.common import MAX_POSES, Pose, Units
from app.schemas.frame_checks import FrameCheck
from app.schemas.frame_sessions import FrameSession, FrameTouchAdd
from app.schemas.results import Calibration
from app.schemas.sessions import (
    DEFAULT_PLAN_TOUCHES,
    Estimate,
    NextTouch,
    PlannedTouch,
    PlanRequest,
    SessionFinish,
    TouchAdd,
)
from app.schemas.sessions import Plan as PlanOut
from app.schemas.sessions import Session as SessionOut
from app.security.auth import Principal, transaction_for
from app.services import idempotency
from app.services.calibrations import grading, writes
from app.services.calibrations.contexts import DbContext
from app.services.controllers import capture
from app.services.robots.robots import get_robot
from app.services.sessions import frame_rechecks, frame_sessions, rows
from app.services.sessions.rows import shown, units_of
from app.services.sessions.rows import start as start_session
from app.services.tools.tools import get_tool
from app.services.touches.diagnosis import one_touch_fits, refusing_mix_ups
from app.services.touches.tool_frames import active_frame, parse_poses_with
from app.services.visible import in_scope, visible_tool
from app.solvers.npoint import NOISE_CONTRADICTED
from app.solvers.numbering import number
from app.solvers.planning import Cone, next_touch, plan_touches, smallest_plan, tilt_lean_spin
from app.storage.models import Calibration as CalibrationRow
from app.storage.models import GuidedSession, Tool, utcnow
from app.words import AuditAction, PoseFormat

#: The TCP assumed when neither the request nor the tool gives one (mm, flange frame).
DEFAULT_TCP_MM = (0.0, 0.0, 150.0)
#: Touches needed before a miss can be told from the rest.
OUTLIER_MIN_TOUCHES = 5
MIN_SOLVE_TOUCHES = 4
_TOO_FEW_TO_NAME = "; a miss is named from 5 touches"


# ---- planning -------------------------------------------------------------------------------
def plan(session: Session, data: PlanRequest) -> PlanOut:
    """N flange poses in the request's format that put the approximate TCP on the point."""
    kinematics = None
    tcp = np.asarray(data.tcp_mm if data.tcp_mm is not None else DEFAULT_TCP_MM, dtype=float)
    if data.tool_id is not None:
        tool = visible_tool(session, data.tool_id)
        if tool is None or tool.archived_at is not None:
            raise InvalidInput(
                "unknown-reference",
                f"no tool {data.tool_id} in service; name a live tool or give tcp_mm",
                loc=("body", "tool_id"),
            )
        kinematics = get_robot(session, tool.robot_id).kinematics
        frame = active_frame(session, tool)
        if frame is not None:
            tcp = np.asarray(frame.position_mm, dtype=float)
    rotations, flanges = parse_poses_with(
        kinematics, data.format, [data.start], data.units, loc=("body", "start")
    )
    cone = Cone(data.max_tilt_deg, data.max_spin_deg)
    if data.target_sigma_mm is None:
        chosen = plan_touches(data.n_poses or DEFAULT_PLAN_TOUCHES, cone)
    else:
        found = smallest_plan(data.target_sigma_mm, data.touch_noise_mm, cone)
        if found is None:
            best = plan_touches(30, cone).total_sigma_mm(data.touch_noise_mm)
            raise InvalidInput(
                "target-unreachable",
                f"with touch noise {data.touch_noise_mm:g} mm, 30 touches within "
                f"{data.max_tilt_deg:g} deg of tilt and {data.max_spin_deg:g} deg of spin reach "
                f"{best:.4f} mm at best, more than the target {data.target_sigma_mm:g} mm: "
                "allow more tilt or spin, or touch with less noise",
                loc=("body", "target_sigma_mm"),
                members={"best_sigma_mm": best},
            )
        chosen = found
    if not np.all(np.isfinite(chosen.unit_covariance)):
        raise InvalidInput(
            "insufficient-spread",
            "a cone this narrow cannot determine the TCP: allow tilt above 0 deg",
            loc=("body", "max_tilt_deg"),
        )
    start = Rotation.from_matrix(rotations[0])
    point = flanges[0] + start.apply(tcp)
    poses = _poses_towards(
        start,
        chosen.tilt_deg,
        chosen.azimuth_deg,
        chosen.spin_deg,
        tcp,
        point,
        data.format,
        data.units,
    )
    sigma = chosen.sigma_mm(data.touch_noise_mm)
    return PlanOut(
        n_poses=len(poses),
        poses=poses,
        predicted_tcp_sigma_mm=[float(v) for v in sigma],
        predicted_sigma_mm=chosen.total_sigma_mm(data.touch_noise_mm),
        touches=[
            PlannedTouch(tilt_deg=float(t), azimuth_deg=float(a), spin_deg=float(s))
            for t, a, s in zip(chosen.tilt_deg, chosen.azimuth_deg, chosen.spin_deg, strict=True)
        ],
    )


def _poses_towards(
    start: Rotation,
    tilt: FloatArray,
    azimuth: FloatArray,
    spin: FloatArray,
    tcp: FloatArray,
    point: FloatArray,
    fmt: PoseFormat,
    units: Units | None,
) -> list[Pose]:
    rotations = cone_rotations(start, tilt, azimuth, spin)
    flanges = flange_positions(rotations, tcp, point)
    unit_map = units.model_dump(exclude_none=True) if units else None
    return [
        pose_to_format(fmt, r, f, units=unit_map)
        for r, f in zip(rotations.as_matrix(), flanges, strict=True)
    ]


# ---- sessions -------------------------------------------------------------------------------
def create_session(
    session: Session, *, tool_id: str, data: SessionCreate, actor: Principal
) -> SessionOut:
    tool = get_tool(session, tool_id)
    row = GuidedSession(
        tool_id=tool.id,
        method=data.method,
        format=data.format,
        units=data.units.model_dump(exclude_none=True) if data.units else None,
        target_sigma_mm=data.target_sigma_mm,
        max_tilt_deg=data.max_tilt_deg,
        max_spin_deg=data.max_spin_deg,
        options=data.options.model_dump(exclude_none=True),
    )
    start_session(session, row, actor=actor, robot_id=tool.robot_id)
    return view(session, row)


def get_session(session: Session, session_id: str, *, for_update: bool = False) -> GuidedSession:
    """A guided session of a tool the caller's key may see, or 404."""
    stmt = in_scope(
        session,
        select(GuidedSession)
        .join(Tool, Tool.id == GuidedSession.tool_id)
        .where(GuidedSession.id == session_id),
        Tool.robot_id,
    )
    if for_update:
        stmt = stmt.with_for_update(of=GuidedSession)
    row = session.scalars(stmt).one_or_none()
    if row is None:
        raise NotFound(f"no session with id {session_id}")
    return row


def list_sessions(
    session: Session, *, tool_id: str, limit: int, cursor: str | None
) -> tuple[list[SessionOut], str | None]:
    """A tool's guided sessions, newest first (an open one can be resumed)."""
    tool = get_tool(session, tool_id)
    rows, next_cursor = paginate(
        session,
        select(GuidedSession).where(
            GuidedSession.tool_id == tool.id, GuidedSession.frame_id.is_(None)
        ),
        created_col=GuidedSession.created_at,
        id_col=GuidedSession.id,
        limit=limit,
        cursor=cursor,
        newest_first=True,
    )
    return [view(session, r, tool=tool) for r in rows], next_cursor


def keep_touches(session: Session, *, calibration_id: str, touches: list[JsonObject]) -> None:
    """The calibration a session finished keeps where each of its touches came from."""
    row = session.get(CalibrationRow, calibration_id)
    assert row is not None  # just stored
    row.touches = list(touches)


def _open(session: Session, session_id: str, *, for_update: bool = True) -> GuidedSession:
    row = get_session(session, session_id, for_update=for_update)
    if row.status != "open":
        raise Conflict(
            f"session {session_id} is finished (calibration "
            f"{row.calibration_id or row.frame_calibration_id}): "
            "start a new session to touch again"
        )
    return row


def _touch_event(
    session: Session,
    row: GuidedSession,
    action: AuditAction,
    actor: Principal,
    details: JsonObject,
    version: int | None = None,
) -> None:
    """The audit event of a change to a session's touches (index: 0-based, as in the URL)."""
    tool = session.get(Tool, row.tool_id)
    rows.event(
        session,
        row,
        action,
        actor,
        details,
        robot_id=None if tool is None else tool.robot_id,
        version=version,
    )


def add_touch_request(*, session_id: str, data: TouchAdd, actor: Principal) -> SessionOut:
    """POST /v1/sessions/{id}/poses: a typed pose, or (`capture`) one read from the tool's
    robot's controller with no transaction open meanwhile, then added as a typed one is."""
    captured = None
    pose = data.pose
    if data.format is not None:
        with transaction_for(actor, write=False) as session:
            _same_format(_open(session, session_id, for_update=False), data.format)
    if data.capture:
        with transaction_for(actor, write=False) as session:
            row = _open(session, session_id, for_update=False)  # refused before any I/O
            tool = session.get(Tool, row.tool_id)
            assert tool is not None
            settings = capture.settings_for_robot(session, tool.robot_id)
            fmt, units = row.format, units_of(row)
        captured = capture.read_still(settings, robot_id=tool.robot_id)
        pose = capture.pose_in_format(captured, fmt, units, loc=("body", "capture"))
    assert pose is not None  # TouchAdd holds a pose or capture
    with transaction_for(actor, write=True) as session:
        return add_touch(session, session_id=session_id, pose=pose, actor=actor, captured=captured)


def _same_format(row: GuidedSession, fmt: PoseFormat) -> None:
    """Refuse a touch that says it is in another format than the session reads its poses in:
    read as the session's, its numbers would be another pose (issue 51: kuka_abc A B C
    0 0 -155 read as techman_rxyz rx ry rz). /invalid-pose, not /validation: the body is
    what the schema allows (any format), and the session's state refuses it."""
    if fmt != row.format:
        raise InvalidInput(
            "invalid-pose",
            f"session {row.id} reads its poses as {row.format}, not {fmt}: send the pose as "
            f"{row.format} (a touch is never converted), or start a session in {fmt}",
            loc=("body", "format"),
        )


def add_touch(
    session: Session,
    *,
    session_id: str,
    pose: Pose,
    actor: Principal,
    captured: capture.Capture | None = None,
) -> SessionOut:
    """Keep one more touch, unless it cannot be read or the set now reads as a unit or
    convention mix-up: then refuse it and leave the session as it was. `captured`: the
    controller's reading the pose was converted from (kept with the touch)."""
    row = _open(session, session_id)
    if len(row.poses) >= MAX_POSES:
        raise InvalidInput(
            "validation",
            f"the session holds {MAX_POSES} touches, the most a calibration takes: finish it",
            loc=("body", "pose"),
        )
    tool, ctx = _context(session, row)

    def flange(fmt: PoseFormat, units: Units | None) -> FloatArray:
        # Arity, NaN, sentinels, a non-rotation: refused for this touch, named at body.pose
        # and by its number in the session.
        with one_pose(("body", "pose"), number(len(row.poses))):
            return ctx.parse_poses(fmt, [pose], units, loc=("body", "pose"))[1]

    # Out of range as the session reads it (a pendant's degrees read as radians, say) but
    # plausible under one other reading: a mix-up, refused as one from the first touch on.
    with refusing_mix_ups(row.format, units_of(row), one_touch_fits, flange, poses_field="pose"):
        flange(row.format, units_of(row))
    poses = [*row.poses, pose]
    if len(poses) >= MIN_SOLVE_TOUCHES:
        try:
            grading.solve(_request(row, poses), ctx)
        except InvalidInput as refusal:
            if refusal.kind == "convention-mismatch":
                raise
    record = capture.typed_touch() if captured is None else captured.touch_record()
    row.poses, row.touches = poses, [*_touch_records(row), record]
    row.updated_at = utcnow()
    details: JsonObject = {"index": len(poses) - 1, "pose": pose, **record}
    _touch_event(session, row, "session.touch_add", actor, details)
    return view(session, row, tool=tool)


def _touch_records(row: GuidedSession) -> list[JsonObject]:
    """One record per kept pose, in order."""
    return [dict(t) for t in row.touches]


def delete_touch(
    session: Session, *, session_id: str, index: int, actor: Principal
) -> SessionOut | FrameSession:
    row = _open(session, session_id)
    held = len(row.poses)
    if not row.poses:
        raise NotFound(f"session {session_id} holds no touches yet: there is none to delete")
    if not 0 <= index < held:
        which = "touch 1, index 0" if held == 1 else f"touches 1 to {held}, indices 0 to {held - 1}"
        raise NotFound(
            f"session {session_id} has no touch at index {index}: it holds {held} ({which}; "
            "touch n is index n - 1)"
        )
    if row.frame_id is not None:
        return frame_sessions.delete_touch(session, row, index=index, actor=actor)
    removed = row.poses[index]
    row.poses = [p for i, p in enumerate(row.poses) if i != index]
    row.touches = [t for i, t in enumerate(_touch_records(row)) if i != index]
    row.updated_at = utcnow()
    _touch_event(session, row, "session.touch_delete", actor, {"index": index, "pose": removed})
    return view(session, row)


def finish_request(
    *, session_id: str, data: SessionFinish, idempotency_key: str | None, actor: Principal
) -> tuple[Calibration | JsonObject | FrameCheck, bool]:
    """POST /v1/sessions/{id}/finish: a recheck session's as the frame's check (its own
    transactions, a deployment's I/O with none open); every other one's in one transaction."""
    with transaction_for(actor, write=False) as session:
        recheck = frame_rechecks.is_recheck(get_session(session, session_id))
    if recheck:
        done = frame_rechecks.finish_request(
            row_id=session_id, idempotency_key=idempotency_key, actor=actor, get_row=get_session
        )
        return done.check, done.replayed
    with transaction_for(actor, write=True) as session:
        return finish(
            session,
            session_id=session_id,
            data=data,
            idempotency_key=idempotency_key,
            actor=actor,
        )


def finish(
    session: Session,
    *,
    session_id: str,
    data: SessionFinish,
    idempotency_key: str | None,
    actor: Principal,
) -> tuple[Calibration | JsonObject, bool]:
    """Store the kept touches as a calibration, exactly as POST /calibrations would (a frame
    session's as POST /v1/frames/{id}/calibrations would: its document as JSON)."""
    row = get_session(session, session_id, for_update=True)
    if row.frame_id is not None:
        return frame_sessions.finish(
            session, row, data=data, idempotency_key=idempotency_key, actor=actor
        )
    body: JsonObject = {
        "method": row.method,
        "format": row.format,
        "poses": list(row.poses),
        "options": dict(row.options),
        "activate": data.activate,
    }
    if row.units:
        body["units"] = dict(row.units)
    if data.note is not None:
        body["note"] = data.note
    if row.status != "open" and idempotency_key is not None:
        fingerprint = idempotency.request_fingerprint(row.tool_id, body)
        replay = idempotency.replay(
            session, actor=actor, key=idempotency_key, fingerprint=fingerprint
        )
        if replay is not None:
            return Calibration.model_validate(replay), True
    if row.status != "open":
        raise Conflict(f"session {session_id} is already finished: {row.calibration_id}")
    if len(row.poses) < MIN_SOLVE_TOUCHES:
        raise InvalidInput(
            "too-few-poses",
            f"the session holds {len(row.poses)} touches; at least {MIN_SOLVE_TOUCHES} are "
            "needed to calibrate: add touches (POST .../poses) before finishing",
            loc=("path", "session_id"),
        )
    out, replayed = writes.submit(
        session,
        tool_id=row.tool_id,
        request=CALIBRATION_REQUESTS.validate_python(body),
        raw_body=body,
        idempotency_key=idempotency_key,
        actor=actor,
    )
    row.status, row.calibration_id, row.updated_at = "finished", out.id, utcnow()
    if not replayed:
        keep_touches(session, calibration_id=out.id, touches=_touch_records(row))
        _touch_event(
            session,
            row,
            "session.finish",
            actor,
            # what the controller printed for each captured touch, in the calibration's audit
            {"calibration_id": out.id, "touches": len(row.poses), "sources": row.touches},
            version=out.version,
        )
    return out, replayed


# ---- what a session shows -------------------------------------------------------------------
def view_any(session: Session, row: GuidedSession) -> SessionOut | FrameSession:
    """A tool's session or a frame's, as a client sees it."""
    return view(session, row) if row.frame_id is None else frame_sessions.view(session, row)


def add_any_touch(
    *, session_id: str, data: TouchAdd | FrameTouchAdd, actor: Principal
) -> SessionOut | FrameSession:
    """POST /v1/sessions/{id}/poses, a tool's session's touch or a frame's."""
    if isinstance(data, FrameTouchAdd):
        return frame_sessions.add_touch_request(
            row_id=session_id, data=data, actor=actor, open_row=_open
        )
    return add_touch_request(session_id=session_id, data=data, actor=actor)


def read_touch(*, session_id: str, raw: object, actor: Principal) -> TouchAdd | FrameTouchAdd:
    """POST /v1/sessions/{id}/poses' body as its session reads one: a tool session's
    TouchAdd, a frame session's FrameTouchAdd (404 for a session the key may not see;
    pydantic's ValidationError when the body is not one)."""
    with transaction_for(actor, write=False) as session:
        frame = get_session(session, session_id).frame_id is not None
    model, other = (FrameTouchAdd, TouchAdd) if frame else (TouchAdd, FrameTouchAdd)
    _no_field_of_the_other_kind(session_id, raw, model, other, frame=frame)
    return model.model_validate(raw)


def _no_field_of_the_other_kind(
    session_id: str,
    raw: object,
    model: type[TouchAdd | FrameTouchAdd],
    other: type[TouchAdd | FrameTouchAdd],
    *,
    frame: bool,
) -> None:
    """422 /invalid-pose naming a field only the other kind of session's touch has (a tool
    session sent `nominal_mm`): the body is one the route's schema allows (either touch),
    so it is the session that refuses it, not the schema (/validation)."""
    if not isinstance(raw, dict):
        return
    foreign = sorted(
        name for name in raw if name in other.model_fields and name not in model.model_fields
    )
    if foreign:
        kind, others = ("a frame's", "a tool's") if frame else ("a tool's", "a frame's")
        raise InvalidInput(
            "invalid-pose",
            f"session {session_id} is {kind} session: {', '.join(foreign)} belong to "
            f"{others} session's touches; leave them out",
            loc=("body", foreign[0]),
        )


def view(session: Session, row: GuidedSession, *, tool: Tool | None = None) -> SessionOut:
    """The session as a client sees it, computed from its stored touches."""
    if tool is None:
        tool, ctx = _context(session, row)
    else:
        ctx = DbContext(session, tool, get_robot(session, tool.robot_id))
    target = row.target_sigma_mm or effective_tolerance(tool.tolerance).max_rms_mm / 2.0
    poses = list(row.poses)
    reading = _read(row, poses, ctx)
    done = _progress(reading, target, open_session=row.status == "open")
    estimate, outliers, messages = reading.estimate, reading.outliers, reading.messages
    next_pose = None
    if row.status == "open" and poses and not done:
        next_pose = _next_pose(ctx, row, poses, outliers, estimate, reading.point, messages)
    next_words = None if next_pose is None else _in_words(ctx, row, poses[0], next_pose)
    return SessionOut(
        **shown(row),
        n_poses=len(poses),
        poses=poses,
        touches=capture.touch_sources(_touch_records(row)),
        estimate=estimate,
        outliers=outliers,
        next_pose=next_pose,
        next_touch=next_words,
        residuals_mm=reading.residuals_mm,
        done=done,
        target_sigma_mm=target,
        messages=messages,
        calibration_id=row.calibration_id,
    )


@dataclass
class _Reading:
    """What the kept touches say so far, and the sentences that say it."""

    estimate: Estimate | None = None
    outliers: list[int] = field(default_factory=list)
    point: list[float] | None = None  # the touched point, as estimated with the TCP
    residuals_mm: list[float] | None = None  # each touch's, with the estimate
    trusted: bool = False  # accepted, and the touch noise not contradicted
    messages: list[str] = field(default_factory=list)


def _read(row: GuidedSession, poses: Sequence[Pose], ctx: DbContext) -> _Reading:
    """Solve the touches as a calibration would (from MIN_SOLVE_TOUCHES on); misses are named
    from OUTLIER_MIN_TOUCHES on."""
    reading = _Reading()
    if len(poses) < MIN_SOLVE_TOUCHES:
        reading.messages.append(
            f"{len(poses)} of at least {MIN_SOLVE_TOUCHES} touches: keep touching the point"
            + (" from the suggested pose" if poses else "")
        )
        return reading
    try:
        result = grading.solve(_request(row, poses), ctx).result
    except InvalidInput as refusal:
        reading.messages.append(f"no estimate yet: {refusal.detail}")
        return reading
    quality = result.quality
    if quality.tcp_sigma_mm is not None and quality.rms_mm is not None:
        reading.estimate = Estimate(
            tcp_mm=result.tcp.position_mm, tcp_sigma_mm=quality.tcp_sigma_mm, rms_mm=quality.rms_mm
        )
    reading.point = result.reference_point_mm
    reading.residuals_mm = list(quality.residuals_mm) if reading.estimate else None
    if len(poses) >= OUTLIER_MIN_TOUCHES:
        reading.outliers = list(quality.outliers)
        reading.messages += [
            _miss_message(row.id, i, quality.residuals_mm[i]) for i in reading.outliers
        ]
    reading.trusted = result.status == "accepted" and not any(
        NOISE_CONTRADICTED in w for w in result.warnings
    )
    if not reading.trusted and not reading.outliers:
        reading.messages.append(
            f"the touches disagree more than the touch noise explains (rms "
            f"{quality.rms_mm or 0.0:.3f} mm): touch on"
            + (_TOO_FEW_TO_NAME if len(poses) < OUTLIER_MIN_TOUCHES else "")
        )
    return reading


def _progress(reading: _Reading, target: float, *, open_session: bool) -> bool:
    """Whether an open session is done (a trusted estimate, no miss, its largest 1-sigma
    within the target), saying how well the TCP is known when the estimate is trusted."""
    if reading.estimate is None or not reading.trusted or reading.outliers:
        return False
    worst = max(reading.estimate.tcp_sigma_mm)
    done = open_session and worst <= target
    if done:
        reading.messages.append(
            f"done: the TCP is known to {worst:.3f} mm (1 sigma, largest axis), within the "
            f"target {target:g} mm; finish to store it"
        )
    else:
        reading.messages.append(
            f"the TCP is known to {worst:.3f} mm (1 sigma, largest axis); target {target:g} mm"
        )
    return done


def _miss_message(session_id: str, index: int, residual_mm: float) -> str:
    return (
        f"touch {index + 1} (index {index}) is {residual_mm:.2f} mm off the others, more than "
        f"the touch noise explains: touch the point again, then delete it "
        f"(DELETE /v1/sessions/{session_id}/poses/{index})"
    )


def _next_pose(
    ctx: DbContext,
    row: GuidedSession,
    poses: Sequence[Pose],
    outliers: Sequence[int],
    estimate: Estimate | None,
    point: Sequence[float] | None,
    messages: list[str],
) -> Pose | None:
    rotations, flanges = ctx.parse_poses(row.format, poses, units_of(row), loc=("poses",))
    start = Rotation.from_matrix(rotations[0])
    if estimate is not None and point is not None:
        tcp, target_point = np.asarray(estimate.tcp_mm), np.asarray(point)
    else:
        frame = ctx.active_frame()
        tcp = np.asarray(frame.position_mm if frame else DEFAULT_TCP_MM, dtype=float)
        target_point = flanges[0] + start.apply(tcp)
    kept = [i for i in range(len(poses)) if i not in set(outliers)]
    relative = np.einsum("ji,njk->nik", rotations[0], rotations[kept])
    tilt, azimuth, spin = next_touch(relative, _cone(row))
    try:
        return _poses_towards(
            start,
            np.array([tilt]),
            np.array([azimuth]),
            np.array([spin]),
            tcp,
            target_point,
            row.format,
            units_of(row),
        )[0]
    except InvalidInput as refusal:  # joints: a pose cannot be written as joint angles
        messages.append(f"no suggested pose: {refusal.detail}")
        return None


def _in_words(ctx: DbContext, row: GuidedSession, first: Pose, suggested: Pose) -> NextTouch:
    """The suggested pose against the first touch, both read as the session reads its poses."""
    rotations, _ = ctx.parse_poses(row.format, [first, suggested], units_of(row), loc=("poses",))
    tilt, lean, spin = tilt_lean_spin(rotations[0], rotations[1])
    return NextTouch(tilt_deg=tilt, lean_deg=lean, spin_deg=spin)


def _cone(row: GuidedSession) -> Cone:
    """A tool session's reachable cone (a frame session has none)."""
    assert row.max_tilt_deg is not None
    assert row.max_spin_deg is not None
    return Cone(row.max_tilt_deg, row.max_spin_deg)


def _request(row: GuidedSession, poses: Sequence[Pose]) -> MethodRequest:
    body: JsonObject = {
        "method": row.method,
        "format": row.format,
        "poses": list(poses),
        "options": dict(row.options),
    }
    if row.units:
        body["units"] = dict(row.units)
    return CALIBRATION_REQUESTS.validate_python(body)


def _context(session: Session, row: GuidedSession) -> tuple[Tool, DbContext]:
    tool = session.get(Tool, row.tool_id)
    assert tool is not None
    return tool, DbContext(session, tool, get_robot(session, tool.robot_id))
