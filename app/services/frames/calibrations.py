"""Frame calibrations (contract v1.4 "Frame touches and methods"): a submission solved by its
frame method (app.methods.frame) against the database-backed context, graded against the
frame's tolerance, stored as a FrameCalibration and the frame's next version through the
lifecycle (activated as `activate` allows, as a tool's), with the fiducials it keeps; the
audit events and the outbox as every version's. Retry-safe with an Idempotency-Key.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import located_in
from app.helpers.pagination import paginate
from app.helpers.tolerance import grade
from app.jsontypes import JsonObject
from app.methods.frame import frame_method_of
from app.methods.frame.base import FrameMethodRequest, FrameSolved
from app.schemas.frame_results import FrameValue
from app.schemas.frame_tolerance import FrameTolerance
from app.schemas.frames import FrameCalibration as FrameCalibrationOut
from app.security.auth import Principal
from app.services import idempotency
from app.services.audit import writes as audit
from app.services.frames.context import FrameDbContext
from app.services.frames.frames import frame_tolerance, get_frame
from app.services.frames.subject import FRAME
from app.services.lifecycle import versions as lifecycle
from app.services.lifecycle.activation import activation_due, held_for_change
from app.services.lifecycle.subject import Locked
from app.services.robots.robots import get_robot
from app.storage.models import Frame, FrameCalibration, FrameFiducial, FrameVersion, new_id, utcnow
from app.words import ActivationKind, Status


def change_from(
    solved: FrameSolved, active: FrameVersion | None
) -> tuple[float | None, float | None]:
    """How far the new frame is from the active one: the largest move of a fiducial (the
    origin when it keeps none) in mm, and the rotation between them in deg."""
    if active is None:
        return None, None
    new = Rotation.from_quat(solved.quaternion, scalar_first=True)
    old = Rotation.from_quat(active.quaternion, scalar_first=True)
    nominal = np.array([f.nominal_mm for f in solved.fiducials] or [[0.0, 0.0, 0.0]])
    moved = (new.apply(nominal) + solved.position_mm) - (
        old.apply(nominal) + np.asarray(active.position_mm, dtype=float)
    )
    angle = float(np.degrees((old.inv() * new).magnitude()))
    return float(np.linalg.norm(moved, axis=1).max()), angle


@dataclass(frozen=True)
class _Graded:
    """A solved frame against its tolerance and the active frame."""

    status: Status
    warnings: list[str]
    change_mm: float | None
    change_deg: float | None


def _graded(
    session: Session, frame: Frame, solved: FrameSolved, tolerance: FrameTolerance
) -> _Graded:
    status, reasons = grade(solved.quality, tolerance, graded=solved.graded, of=FRAME.kind)
    active = (
        None
        if frame.active_version is None
        else lifecycle.active_version_row(session, FRAME, frame)
    )
    change_mm, change_deg = change_from(solved, active)
    warnings = [*solved.warnings, *reasons]
    if change_mm is not None and held_for_change(change_mm, tolerance):
        warnings.append(
            f"the frame moved {change_mm:.2f} mm from the active one, more than max_change_mm "
            f"{tolerance.max_change_mm:g} mm: stored, not activated by auto; activate it by "
            f"POST /v1/frames/{frame.id}/versions/{{version}}/activate once checked"
        )
    return _Graded(status, warnings, change_mm, change_deg)


def submit(
    session: Session,
    *,
    frame_id: str,
    request: FrameMethodRequest,
    raw_body: JsonObject,
    idempotency_key: str | None,
    actor: Principal,
) -> tuple[JsonObject, bool]:
    """Solve, grade and store a frame calibration: (its document as JSON, replayed). The same
    Idempotency-Key with the same body answers the first document again, no new version; with
    another body 409. Unsolvable input is a 422 rooted at the body, and writes nothing."""
    locked = lifecycle.lock(session, FRAME, frame_id)  # serialises the frame's versions
    fingerprint = idempotency.request_fingerprint(frame_id, raw_body)
    if idempotency_key is not None:
        kept = idempotency.replay(
            session, actor=actor, key=idempotency_key, fingerprint=fingerprint
        )
        if kept is not None:
            return kept, True
    frame = get_frame(session, frame_id)
    robot = get_robot(session, frame.robot_id)
    with located_in("body"):
        solved = frame_method_of(request).solve(request, FrameDbContext(session, frame, robot))
    tolerance = frame_tolerance(frame.tolerance)
    graded = _graded(session, frame, solved, tolerance)
    row = FrameCalibration(
        id=new_id(),
        frame_id=frame_id,
        method=request.method,
        status=graded.status,
        request=raw_body,
        result={},
        points_mm=[[float(v) for v in p] for p in solved.points_mm],
        pointer_tool_id=None if solved.tool is None else solved.tool.tool_id,
        pointer_version=None if solved.tool is None else solved.tool.version,
        created_at=utcnow(),
        created_by=actor.name,
    )
    session.add(row)
    session.flush()
    due = activation_due(request.activate, graded.status, graded.change_mm, tolerance)
    row.version = _versioned(session, locked, row, request, solved, due, actor)
    _keep_fiducials(session, row, solved)
    answer = _answer(row, solved, graded, active=due is not None)
    row.result = {k: v for k, v in answer.items() if k != "active"}
    audit.record(
        session,
        actor=actor,
        action="calibration.create",
        resource_type="calibration",
        resource_id=row.id,
        robot_id=frame.robot_id,
        about={FRAME.key: frame_id},
        version=row.version,
        details={"method": request.method, "status": graded.status, "note": request.note},
    )
    if idempotency_key is not None:
        idempotency.remember(
            session, actor=actor, key=idempotency_key, fingerprint=fingerprint, response=answer
        )
    return answer, False


def _versioned(
    session: Session,
    locked: Locked,
    row: FrameCalibration,
    request: FrameMethodRequest,
    solved: FrameSolved,
    due: ActivationKind | None,
    actor: Principal,
) -> int:
    """The calibration's frame as the frame's next version, activated when `due`; its number."""
    version = lifecycle.add_version(
        session,
        FRAME,
        locked=locked,
        position_mm=[float(v) for v in solved.position_mm],
        quaternion=[float(v) for v in solved.quaternion],
        source=request.method,
        status=row.status,
        calibration_id=row.id,
        note=request.note,
        actor=actor,
        created_at=row.created_at,
        deferred=True,
    )
    if due is not None:
        lifecycle.activate(
            session, FRAME, locked=locked, version=version, reason=due, actor=actor, deferred=True
        )
    lifecycle.save_deferred(session, FRAME, locked)
    return version


def _answer(
    row: FrameCalibration, solved: FrameSolved, graded: _Graded, *, active: bool
) -> JsonObject:
    """The calibration's document as JSON."""
    document = FrameCalibrationOut(
        id=row.id,
        frame_id=row.frame_id,
        method=row.method,
        status=row.status,
        frame=FrameValue(
            position_mm=[float(v) for v in solved.position_mm],
            quaternion=[float(v) for v in solved.quaternion],
        ),
        quality=solved.quality,
        points_mm=row.points_mm,
        tool=solved.tool,
        warnings=graded.warnings,
        summary=solved.summary,
        fiducials=solved.fiducials,
        version=row.version,
        active=active,
        change_from_active_mm=graded.change_mm,
        change_from_active_deg=graded.change_deg,
        created_at=row.created_at,
        created_by=row.created_by,
    )
    answer: JsonObject = document.model_dump(mode="json")
    return answer


def _keep_fiducials(session: Session, row: FrameCalibration, solved: FrameSolved) -> None:
    """The calibration's fiducials, each with where the new frame puts it in the base frame."""
    rotation = Rotation.from_quat(solved.quaternion, scalar_first=True)
    for seq, fiducial in enumerate(solved.fiducials):
        point = rotation.apply(np.asarray(fiducial.nominal_mm, dtype=float)) + solved.position_mm
        session.add(
            FrameFiducial(
                frame_id=row.frame_id,
                calibration_id=row.id,
                seq=seq,
                name=fiducial.name,
                nominal_mm=[float(v) for v in fiducial.nominal_mm],
                point_mm=[float(v) for v in point],
            )
        )


def document_of(row: FrameCalibration, frame: Frame) -> FrameCalibrationOut:
    """A stored calibration as the API shows it (whether its version is active now)."""
    return FrameCalibrationOut.model_validate(
        {**row.result, "active": row.version is not None and frame.active_version == row.version}
    )


def list_calibrations(
    session: Session, *, frame_id: str, limit: int, cursor: str | None
) -> tuple[Sequence[FrameCalibrationOut], str | None]:
    """A frame's calibrations, oldest first."""
    frame = get_frame(session, frame_id)
    stmt = select(FrameCalibration).where(FrameCalibration.frame_id == frame_id)
    rows, next_cursor = paginate(
        session,
        stmt,
        created_col=FrameCalibration.created_at,
        id_col=FrameCalibration.id,
        limit=limit,
        cursor=cursor,
    )
    return [document_of(r, frame) for r in rows], next_cursor
