"""What a re-check after a move changes (contract v1.4 "After a move: re-register"): the
frame carried by the shift as a new version activated with kind `check_correction`, and, when
the robot itself moved (`scope` "robot"), every other live frame of the robot and each of its
reference points carried by the same shift, in the check's transaction.

A frame's version and activation are the lifecycle's (app.services.lifecycle.versions): the
correction is a version as a calibration's is, never a copy of activation. A reference point
has no versions: its position is moved in place and the move audited (`reference_point.move`,
with where it was, where it is, the shift and the reason), so it can be read back and undone.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import get_args

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.arrays import FloatArray
from app.jsontypes import JsonArray, JsonObject
from app.schemas.frame_checks import MovedSubject
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.frames.subject import FRAME
from app.services.lifecycle import versions as lifecycle
from app.services.lifecycle.activation import CHECK_CORRECTION
from app.solvers.frame.shift import Shift
from app.storage.models import Frame, ReferencePoint
from app.words import FitPoints

#: A correction's version is the fit of the stored fiducials to the touches: the fit_points
#: estimator (app.solvers.frame.shift), so it counts among the measured versions of the
#: drift trend as any fit_points calibration does.
CORRECTION_SOURCE: FitPoints = get_args(FitPoints)[0]


@dataclass(frozen=True)
class Pose:
    """A frame's pose in the robot's base frame: rotation (3, 3) frame -> base, origin mm."""

    rotation: FloatArray
    origin_mm: FloatArray

    @staticmethod
    def of(position_mm: JsonArray, quaternion_wxyz: JsonArray) -> Pose:
        w, x, y, z = (float(v) for v in quaternion_wxyz)
        rotation = Rotation.from_quat([x, y, z, w]).as_matrix()
        return Pose(rotation, np.asarray(position_mm, dtype=np.float64))

    def quaternion_wxyz(self) -> list[float]:
        x, y, z, w = Rotation.from_matrix(self.rotation).as_quat()
        q = np.array([w, x, y, z])
        return [float(v) for v in (q if w >= 0 else -q)]


def shift_details(shift: Shift) -> JsonObject:
    """The shift as an audit event keeps it (a robot's other checks within the hour read it)."""
    return {
        "position_mm": [float(v) for v in shift.translation_mm],
        "rotvec_rad": [float(v) for v in Rotation.from_matrix(shift.rotation).as_rotvec()],
    }


def correct_frame(
    session: Session,
    *,
    frame_id: str,
    pose: Pose,
    shift: Shift,
    checked_version: int,
    calibration_id: str | None,
    reason: str | None,
    actor: Principal,
    check_id: str,
) -> tuple[int, float]:
    """The frame carried by the shift, stored and activated (kind check_correction, the
    person's reason): (its new version, how far its origin moved mm). The new version names
    the calibration the checked one did: the fiducials it kept are in frame coordinates, so
    they hold in the corrected frame and are listed and touched again from it."""
    locked = lifecycle.lock(session, FRAME, frame_id)
    rotation, origin = shift.moved(pose.rotation, pose.origin_mm)
    moved = Pose(rotation, origin)
    version = lifecycle.add_version(
        session,
        FRAME,
        locked=locked,
        position_mm=[float(v) for v in origin],
        quaternion=moved.quaternion_wxyz(),
        source=CORRECTION_SOURCE,
        status="accepted",
        calibration_id=calibration_id,
        note=f"re-check correction of version {checked_version} (check {check_id})",
        actor=actor,
    )
    lifecycle.activate(
        session,
        FRAME,
        locked=locked,
        version=version,
        reason=CHECK_CORRECTION,
        reason_text=reason,
        actor=actor,
        details={
            "status": "accepted",
            "checked_version": checked_version,
            "check_id": check_id,
            "shift": shift_details(shift),
        },
    )
    return version, float(np.linalg.norm(origin - pose.origin_mm))


def correct_robot(
    session: Session,
    *,
    robot_id: str,
    checked_frame_id: str,
    shift: Shift,
    reason: str | None,
    actor: Principal,
    check_id: str,
) -> list[MovedSubject]:
    """Every other live frame of the robot with an active version, and every reference point
    of it, carried by the shift (the robot itself moved): each frame a new version activated
    with kind check_correction, each point moved in place and audited. Frames are locked in
    the order of their ids, so two robot-wide corrections never wait on each other crosswise."""
    move = _Move(robot_id, checked_frame_id, shift, reason, actor, check_id)
    return _correct_frames(session, move) + _move_points(session, move)


@dataclass(frozen=True)
class _Move:
    """A robot-wide correction: the robot, the frame whose check found the shift, the shift,
    why, who, and the check."""

    robot_id: str
    checked_frame_id: str
    shift: Shift
    reason: str | None
    actor: Principal
    check_id: str


def _correct_frames(session: Session, move: _Move) -> list[MovedSubject]:
    """Every other live frame of the robot with an active version, corrected."""
    moved: list[MovedSubject] = []
    others = session.scalars(
        select(Frame)
        .where(
            Frame.robot_id == move.robot_id,
            Frame.archived_at.is_(None),
            Frame.id != move.checked_frame_id,
            Frame.active_version.is_not(None),
        )
        .order_by(Frame.id)
    ).all()
    for frame in others:
        locked = lifecycle.lock(session, FRAME, frame.id)
        assert locked.active_version is not None
        row = lifecycle.get_version(
            session, FRAME, subject_id=frame.id, version=locked.active_version
        )
        version, distance = correct_frame(
            session,
            frame_id=frame.id,
            pose=Pose.of(row.position_mm, row.quaternion),
            shift=move.shift,
            checked_version=locked.active_version,
            calibration_id=row.calibration_id,
            reason=move.reason,
            actor=move.actor,
            check_id=move.check_id,
        )
        moved.append(
            MovedSubject(
                kind="frame", id=frame.id, name=frame.name, version=version, moved_mm=distance
            )
        )
    return moved


def _move_points(session: Session, move: _Move) -> list[MovedSubject]:
    """Every reference point of the robot, moved in place and audited."""
    shift = move.shift
    moved: list[MovedSubject] = []
    points = session.scalars(
        select(ReferencePoint)
        .where(ReferencePoint.robot_id == move.robot_id)
        .order_by(ReferencePoint.id)
        .with_for_update()
    ).all()
    for point in points:
        before = np.asarray(point.position_mm, dtype=np.float64)
        after = shift.rotation @ before + shift.translation_mm
        point.position_mm = [float(v) for v in after]
        if point.covariance_mm2:  # the point's own uncertainty turns with it
            cov = np.asarray(point.covariance_mm2, dtype=np.float64)
            point.covariance_mm2 = (shift.rotation @ cov @ shift.rotation.T).tolist()
        audit.record(
            session,
            actor=move.actor,
            action="reference_point.move",
            resource_type="reference_point",
            resource_id=point.id,
            robot_id=move.robot_id,
            about={FRAME.key: move.checked_frame_id},  # the frame whose check moved it
            details={
                "name": point.name,
                "from_mm": [float(v) for v in before],
                "to_mm": point.position_mm,
                "check_id": move.check_id,
                "frame_id": move.checked_frame_id,
                "shift": shift_details(shift),
                "reason": move.reason,
            },
        )
        moved.append(
            MovedSubject(
                kind="reference_point",
                id=point.id,
                name=point.name,
                version=None,
                moved_mm=float(np.linalg.norm(after - before)),
            )
        )
    return moved
