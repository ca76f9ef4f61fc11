"""Guided frame sessions (API.md v1.4 "Sessions:"): a frame calibrated touch by touch with a
pointer tool, each touch typed or captured from the robot's controller (the v1.3 still
check, as a tool session's capture), the next touch said in words (app.methods.frame.
next_role), finished as the frame calibration POST /v1/frames/{id}/calibrations stores
(app.services.frames.calibrations.submit: the one path, never a copy).

A frame session is a guided_sessions row with `frame_id` set: `tool_id` is then the pointer,
each touch's role or nominal_mm is kept in its touch record beside where it came from. As
for a tool's session, everything a client sees is computed from the stored touches on every
read, so any worker or instance continues it; writes lock the row.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, cast

from pydantic import BaseModel, ValidationError
from sqlalchemy.orm import Session

from app.errors import Conflict, InvalidInput, located_in
from app.jsontypes import JsonObject
from app.kinematics.poses import one_pose
from app.methods.frame import FRAME_CALIBRATION_REQUESTS, FRAME_METHODS_BY_NAME
from app.methods.frame.base import FrameSolved
from app.methods.frame.next_role import NextRole, construction_of, next_role
from app.schemas.common import MAX_POSES, Pose
from app.schemas.frame_sessions import (
    FrameEstimate,
    FrameSession,
    FrameSessionCreate,
    FrameSessionOptions,
    FrameSessionTouch,
    FrameTouchAdd,
    NextFrameTouch,
)
from app.schemas.sessions import SessionFinish
from app.security.auth import Principal, transaction_for
from app.services import idempotency
from app.services.controllers import capture
from app.services.frames import calibrations
from app.services.frames.context import FrameDbContext
from app.services.frames.frames import frame_tolerance, get_frame
from app.services.frames.subject import FRAME
from app.services.robots.robots import get_robot
from app.services.sessions import frame_rechecks, rows
from app.services.sessions.rows import shown, units_of
from app.services.sessions.rows import start as start_session
from app.solvers.frame import MAX_ANGLE_SIGMA_DEG
from app.solvers.frame.model import touch_points
from app.solvers.numbering import number
from app.storage.models import Frame, FrameCalibration, GuidedSession, utcnow
from app.words import AuditAction, FrameMethodName


def create(
    session: Session, *, frame_id: str, data: FrameSessionCreate, actor: Principal
) -> FrameSession:
    """POST /v1/frames/{frame_id}/sessions: a session of a method that takes touches, for a
    frame of its kinds (or a recheck of a frame that keeps fiducials), touched with a live
    tool of the frame's robot."""
    frame = get_frame(session, frame_id)
    if data.method == frame_rechecks.RECHECK:
        frame_rechecks.stored_names(session, frame)  # 422 when it keeps none to touch again
    else:
        _check_method(frame, data.method)
    with located_in("body"):
        _context(session, frame).pointer(data.tool_id, None)  # a live tool of the robot
    row = GuidedSession(
        tool_id=data.tool_id,
        frame_id=frame.id,
        method=data.method,
        format=data.format,
        units=data.units.model_dump(exclude_none=True) if data.units else None,
        target_sigma_mm=None,
        max_tilt_deg=None,
        max_spin_deg=None,
        options=data.options.model_dump(exclude_none=True),
    )
    start_session(session, row, actor=actor, robot_id=frame.robot_id, about={FRAME.key: frame.id})
    return view(session, row)


def _check_method(frame: Frame, method: FrameMethodName) -> None:
    """The frame method takes touches and calibrates a frame of this one's kind."""
    entry = FRAME_METHODS_BY_NAME[method]
    if entry.touch_count.max == 0:
        raise InvalidInput(
            "unsupported",
            f"{method} takes no touches: give the frame in one POST "
            f"/v1/frames/{frame.id}/calibrations; a session guides touches",
            loc=("body", "method"),
        )
    if frame.kind not in entry.kinds:
        raise InvalidInput(
            "unsupported",
            f"{method} calibrates a frame of kind {' or '.join(entry.kinds)}, and frame "
            f"{frame.name} is a {frame.kind}: choose another method (GET /v1/methods)",
            loc=("body", "method"),
        )


def add_touch_request(
    *, row_id: str, data: FrameTouchAdd, actor: Principal, open_row: OpenRow
) -> FrameSession:
    """POST /v1/sessions/{id}/poses of a frame session: a typed pose, or (`capture`) one read
    from the frame's robot's controller with no transaction open meanwhile."""
    captured = None
    pose = data.pose
    if data.capture:
        with transaction_for(actor, write=False) as session:
            row = open_row(session, row_id, for_update=False)  # refused before any I/O
            frame = _frame(session, row)
            settings = capture.settings_for_robot(session, frame.robot_id)
            fmt, units = row.format, units_of(row)
        captured = capture.read_still(settings, robot_id=frame.robot_id)
        pose = capture.pose_in_format(captured, fmt, units, loc=("body", "capture"))
    assert pose is not None  # FrameTouchAdd holds a pose or capture
    with transaction_for(actor, write=True) as session:
        row = open_row(session, row_id, for_update=True)
        return add_touch(session, row, data=data, pose=pose, actor=actor, captured=captured)


class OpenRow(Protocol):
    """How the sessions' service reads an open session (the tools' and frames' one rule:
    app.services.sessions.sessions._open, passed in)."""

    def __call__(self, session: Session, session_id: str, *, for_update: bool) -> GuidedSession:
        """The open session, or 404 / 409."""
        ...


def add_touch(
    session: Session,
    row: GuidedSession,
    *,
    data: FrameTouchAdd,
    pose: Pose,
    actor: Principal,
    captured: capture.Capture | None = None,
) -> FrameSession:
    """Keep one more touch, unless its pose cannot be read or it is not what the method
    takes next (a role missing, repeated or unknown; a nominal_mm missing or not taken)."""
    if len(row.poses) >= MAX_POSES:
        raise InvalidInput(
            "validation",
            f"the session holds {MAX_POSES} touches, the most a calibration takes: finish it",
            loc=("body", "pose"),
        )
    frame = _frame(session, row)
    ctx = _context(session, frame)
    with one_pose(("body", "pose"), number(len(row.poses))):
        ctx.parse_poses(row.format, [pose], units_of(row), loc=("body", "pose"))
    if frame_rechecks.is_recheck(row):
        frame_rechecks.check_touch(session, row, frame, data)
    else:
        _check_kind(row, frame, data)
    record: JsonObject = capture.typed_touch() if captured is None else captured.touch_record()
    if data.fiducial is not None:
        record["fiducial"] = data.fiducial
    if data.role is not None:
        record["role"] = data.role
    if data.nominal_mm is not None:
        record["nominal_mm"] = list(data.nominal_mm)
    row.poses, row.touches = [*row.poses, pose], [*_records(row), record]
    row.updated_at = utcnow()
    _event(session, row, frame, "session.touch_add", actor, {"index": len(row.poses) - 1,
           "pose": pose, **record})  # fmt: skip
    return view(session, row)


def _check_kind(row: GuidedSession, frame: Frame, data: FrameTouchAdd) -> None:
    """The touch is what the method takes: its role one the method's construction has and not
    touched yet, a nominal_mm for fit_points and for no other."""
    construction = construction_of(_method(row), _options(row).convention)
    roles = [r.get("role") for r in _records(row)]
    wants_nominal = construction is None
    if wants_nominal and data.nominal_mm is None:
        raise InvalidInput(
            "validation",
            f"{row.method} touches carry nominal_mm, the touched point's coordinates in the "
            "frame (from the fixture's drawing): add them",
            loc=("body", "nominal_mm"),
        )
    if not wants_nominal and data.nominal_mm is not None:
        raise InvalidInput(
            "validation",
            f"{row.method} touches carry a role, not nominal_mm: send the role the session's "
            "next_role names",
            loc=("body", "nominal_mm"),
        )
    if construction is None:
        return
    told = _next(row, frame)
    if data.role is None:
        if told is not None and told.takes == "tip":
            return
        wanted = "" if told is None else f": next is {told.role!r} ({told.words})"
        raise InvalidInput(
            "missing-role",
            f"{row.method} touches carry a role, one of {', '.join(construction.roles)}{wanted}",
            loc=("body", "role"),
        )
    if data.role not in construction.roles:
        raise InvalidInput(
            "missing-role",
            f"{row.method} takes the roles {', '.join(construction.roles)}, not {data.role!r}",
            loc=("body", "role"),
        )
    if data.role in roles:
        raise InvalidInput(
            "repeated-role",
            f"touch {roles.index(data.role) + 1} is already the {data.role!r} touch: each role "
            f"is touched once; delete it first (DELETE /v1/sessions/{row.id}/poses/"
            f"{roles.index(data.role)}) to touch it again",
            loc=("body", "role"),
        )


def delete_touch(
    session: Session, row: GuidedSession, *, index: int, actor: Principal
) -> FrameSession:
    """Remove touch `index` (checked by the caller); later touches move up one index."""
    removed = row.poses[index]
    row.poses = [p for i, p in enumerate(row.poses) if i != index]
    row.touches = [t for i, t in enumerate(_records(row)) if i != index]
    row.updated_at = utcnow()
    frame = _frame(session, row)
    _event(session, row, frame, "session.touch_delete", actor, {"index": index, "pose": removed})
    return view(session, row)


def finish(
    session: Session,
    row: GuidedSession,
    *,
    data: SessionFinish,
    idempotency_key: str | None,
    actor: Principal,
) -> tuple[JsonObject, bool]:
    """Store the kept touches as a frame calibration, exactly as POST /v1/frames/{id}/
    calibrations would: (its document, replayed)."""
    body = _body(row)
    body["activate"] = data.activate
    if data.note is not None:
        body["note"] = data.note
    assert row.frame_id is not None
    if row.status != "open":
        if idempotency_key is not None:  # the finish retried: its answer again
            fingerprint = idempotency.request_fingerprint(row.frame_id, body)
            replay = idempotency.replay(
                session, actor=actor, key=idempotency_key, fingerprint=fingerprint
            )
            if replay is not None:
                return replay, True
        raise Conflict(f"session {row.id} is already finished: {row.frame_calibration_id}")
    told = _next(row, _frame(session, row))
    if told is not None and not told.enough:
        raise InvalidInput(
            "too-few-poses",
            f"the session holds {len(row.poses)} touches and the method needs more: next, "
            f"{told.words}; add it (POST /v1/sessions/{row.id}/poses) before finishing",
            loc=("path", "session_id"),
        )
    try:
        request = FRAME_CALIBRATION_REQUESTS.validate_python(body)
    except ValidationError as refused:
        first = refused.errors()[0]
        raise InvalidInput(
            "validation",
            f"the session's touches do not make a {row.method} calibration: {first['msg']}",
            loc=("path", "session_id"),
        ) from None
    doc, replayed = calibrations.submit(
        session,
        frame_id=row.frame_id,
        request=request,
        raw_body=body,
        idempotency_key=idempotency_key,
        actor=actor,
    )
    if not replayed:
        stored = session.get(FrameCalibration, doc["id"])
        assert stored is not None  # just stored
        stored.touches = _records(row)
        row.status, row.frame_calibration_id, row.updated_at = "finished", stored.id, utcnow()
        _event(
            session,
            row,
            _frame(session, row),
            "session.finish",
            actor,
            {"calibration_id": stored.id, "touches": len(row.poses), "sources": row.touches},
            version=stored.version,
        )
    return doc, replayed


# ---- what a frame session shows -------------------------------------------------------------
def view(session: Session, row: GuidedSession) -> FrameSession:
    """The session as a client sees it, computed from its stored touches."""
    frame = _frame(session, row)
    ctx = _context(session, frame)
    records = _records(row)
    messages: list[str] = []
    points = _points(ctx, row, messages)
    told, estimate, done = _progress(session, ctx, row, frame, messages)
    if told is not None:
        messages.insert(0, f"next: {told.words}")
    if done and estimate is None:
        messages.append(f"the touches make a check: finish to check the frame (POST "
                        f"/v1/sessions/{row.id}/finish)")  # fmt: skip
    elif done:
        messages.append(f"the touches give a frame: finish to store it (POST /v1/sessions/"
                        f"{row.id}/finish)")  # fmt: skip
    return FrameSession(
        **shown(row),
        frame_id=frame.id,
        options=_options(row),
        n_touches=len(row.poses),
        touches=[
            FrameSessionTouch.model_validate(
                {
                    "source": r["source"],
                    "read_at": r.get("read_at"),
                    "readings": r.get("readings"),
                    "index": i,
                    "role": r.get("role"),
                    "fiducial": r.get("fiducial"),
                    "nominal_mm": r.get("nominal_mm"),
                    "pose": row.poses[i],
                    "point_mm": None if points is None else points[i],
                }
            )
            for i, r in enumerate(records)
        ],
        next_role=None if told is None else told.words,
        next=None if told is None else NextFrameTouch(role=told.role, takes=told.takes),
        done=done,
        estimate=estimate,
        messages=messages,
        calibration_id=row.frame_calibration_id,
    )


def _progress(
    session: Session, ctx: FrameDbContext, row: GuidedSession, frame: Frame, messages: list[str]
) -> tuple[NextRole | None, FrameEstimate | None, bool]:
    """(the next touch, the frame so far, whether it can be finished): a recheck's next
    stored fiducial and at least three touched; a calibration's next role and its estimate."""
    is_open = row.status == "open"
    if frame_rechecks.is_recheck(row):
        told = _next_fiducial(session, row, frame) if is_open else None
        return told, None, is_open and len(row.poses) >= frame_rechecks.MIN_FIDUCIALS
    told = _next(row, frame) if is_open else None
    estimate = None
    if is_open and (told is None or told.enough):
        estimate = _estimate(ctx, row, messages)
    return told, estimate, estimate is not None


@dataclass(frozen=True)
class _Noise:
    touch_noise_mm: float | None
    max_angle_sigma_deg: float


def _noise(row: GuidedSession, frame: Frame) -> _Noise:
    """The touch noise and angle limit the next touch's distance is told for: the session's
    options, else the frame's tolerance (the noise) and the methods' default (the limit)."""
    options = _options(row)
    noise = options.touch_noise_mm
    if noise is None:
        noise = frame_tolerance(frame.tolerance).touch_noise_mm
    return _Noise(noise, options.max_angle_sigma_deg or MAX_ANGLE_SIGMA_DEG)


def _next_fiducial(session: Session, row: GuidedSession, frame: Frame) -> NextRole | None:
    """A recheck's next touch: the next stored fiducial not yet touched, in words."""
    name = frame_rechecks.next_fiducial(session, row, frame)
    if name is None:
        return None
    return NextRole(
        role=name,
        takes="fiducial",
        words=f"touch fiducial {name!r} again",
        enough=len(row.poses) >= frame_rechecks.MIN_FIDUCIALS,
    )


def _next(row: GuidedSession, frame: Frame) -> NextRole | None:
    """The next touch of the method after the kept ones, in words."""
    noise = _noise(row, frame)
    return next_role(
        _method(row),
        [r.get("role") for r in _records(row)],
        convention=_options(row).convention,
        touch_noise_mm=noise.touch_noise_mm,
        max_angle_sigma_deg=noise.max_angle_sigma_deg,
    )


def _points(
    ctx: FrameDbContext, row: GuidedSession, messages: list[str]
) -> list[list[float]] | None:
    """Each touch's point in the base frame with the pointer's active TCP (None without)."""
    if not row.poses:
        return []
    try:
        pointer = ctx.pointer(row.tool_id, None)
    except InvalidInput as refusal:
        messages.append(refusal.detail)
        return None
    if pointer is None:
        return None
    rotations, positions = ctx.parse_poses(row.format, row.poses, units_of(row), loc=("poses",))
    points = touch_points(rotations, positions, pointer.pointer.tcp_mm)
    return [[float(v) for v in p] for p in points]


def _estimate(ctx: FrameDbContext, row: GuidedSession, messages: list[str]) -> FrameEstimate | None:
    """The frame the kept touches give, as the calibration's method computes it; its refusal
    (a touch too close, collinear points) as a message."""
    try:
        request = FRAME_CALIBRATION_REQUESTS.validate_python(_body(row))
        with located_in("body"):
            solved: FrameSolved = FRAME_METHODS_BY_NAME[row.method].solve(request, ctx)
    except InvalidInput as refusal:
        messages.append(f"no frame yet: {refusal.detail}")
        return None
    except ValidationError as refused:
        messages.append(f"no frame yet: {refused.errors()[0]['msg']}")
        return None
    quality = solved.quality
    return FrameEstimate(
        position_mm=[float(v) for v in solved.position_mm],
        quaternion=[float(v) for v in solved.quaternion],
        position_sigma_mm=quality.position_sigma_mm,
        angle_sigma_deg=quality.angle_sigma_deg,
        summary=solved.summary,
    )


def _body(row: GuidedSession) -> JsonObject:
    """The calibration body of the kept touches, as POST /v1/frames/{id}/calibrations takes
    it: each touch's role or nominal_mm with its pose, the options the method takes."""
    entry = FRAME_METHODS_BY_NAME[row.method]
    taken = _option_names(entry.request)
    touches: list[JsonObject] = []
    for pose, record in zip(row.poses, _records(row), strict=True):
        touch: JsonObject = {"pose": pose}
        for key in ("role", "nominal_mm"):
            if record.get(key) is not None:
                touch[key] = record[key]
        touches.append(touch)
    body: JsonObject = {
        "method": row.method,
        "tool_id": row.tool_id,
        "format": row.format,
        "touches": touches,
        "options": {k: v for k, v in dict(row.options).items() if k in taken},
    }
    if row.units:
        body["units"] = dict(row.units)
    return body


def _option_names(request: type[BaseModel]) -> set[str]:
    """The options a method's request takes."""
    annotation = request.model_fields["options"].annotation
    assert isinstance(annotation, type)
    assert issubclass(annotation, BaseModel)
    return set(annotation.model_fields)


def _event(
    session: Session,
    row: GuidedSession,
    frame: Frame,
    action: AuditAction,
    actor: Principal,
    details: JsonObject,
    version: int | None = None,
) -> None:
    rows.event(
        session,
        row,
        action,
        actor,
        details,
        robot_id=frame.robot_id,
        about={FRAME.key: frame.id},
        version=version,
    )


def _records(row: GuidedSession) -> list[JsonObject]:
    return [cast(JsonObject, dict(t)) for t in row.touches]


def _method(row: GuidedSession) -> FrameMethodName:
    """The session's frame method (a frame session's row holds one)."""
    assert row.method in FRAME_METHODS_BY_NAME
    return cast(FrameMethodName, row.method)


def _options(row: GuidedSession) -> FrameSessionOptions:
    return FrameSessionOptions.model_validate(row.options)


def _frame(session: Session, row: GuidedSession) -> Frame:
    assert row.frame_id is not None
    found = session.get(Frame, row.frame_id)
    assert found is not None
    return found


def _context(session: Session, frame: Frame) -> FrameDbContext:
    return FrameDbContext(session, frame, get_robot(session, frame.robot_id))
