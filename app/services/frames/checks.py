"""A frame's re-check after a move (contract v1.4 "After a move: re-register", issue 49):
the stored fiducials touched again with a calibrated pointer, the rigid shift that carries
them onto the touches (app.solvers.frame.shift), each fiducial's deviation in the frame's
axes, judged at the fiducials against the frame's tolerance, and, when asked
(`correct`: "within_limits") and the largest deviation lies past check_mm and none past
max_correction_mm, corrected (app.services.frames.moves): the frame, or with `scope` "robot"
every frame and reference point of its robot. Beyond max_correction_mm nothing changes but
the check's record, whose verdict gives the frame the fleet's `check_failed`.

The steps, and why each is where it is: one write transaction under the frame's lock, so a
repeated Idempotency-Key waits for the first request and replays its answer (concurrent
sends: one version); in it, a touch far from the fiducial it names is refused naming the
stored fiducial it is near before any shift is computed, then the check is recorded
(`frame.check`, read back by the drift trend and the fleet), the correction stored and
activated, and the answer kept for the key. The correction's deployment, after that
transaction, is app.services.checks.frame_recheck's (the entry point).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import timedelta

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.arrays import FloatArray
from app.errors import InvalidInput, located_in
from app.jsontypes import JsonObject
from app.schemas.frame_checks import (
    FiducialDeviation,
    FrameCheck,
    FrameCheckCreate,
    FrameCheckVerdict,
    FrameCorrection,
    FrameShift,
)
from app.schemas.frame_results import FramePointer
from app.schemas.frame_tolerance import FrameTolerance
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.frames.fiducials import list_fiducials
from app.services.frames.frames import frame_tolerance
from app.services.frames.moves import Pose, correct_frame, correct_robot, shift_details
from app.services.frames.subject import FRAME
from app.services.lifecycle import drift
from app.services.lifecycle import versions as lifecycle
from app.services.robots.robots import get_robot
from app.services.touches.tool_frames import active_frame, parse_poses_with
from app.solvers.frame.model import touch_points
from app.solvers.frame.shift import Shift, check_near, shift_from_fiducials
from app.storage.models import (
    AuditEvent,
    Frame,
    Tool,
    new_id,
    utcnow,
)
from app.words import FRAME_CHECK_ACTION

#: A touch farther than this many times max_correction_mm (and FAR_MARGIN_MM) from the
#: fiducial it names is not that fiducial moved but another point: it is refused, not judged,
#: so a move a little past the limit is still measured and said (needs_recalibration).
FAR_FACTOR = 4.0
FAR_MARGIN_MM = 10.0
#: Two frames of one robot checked within this long whose shifts differ tell that one
#: fixture moved, not the robot: said, never averaged.
SAME_MOVE_WITHIN = timedelta(hours=1)
#: The check's sentence while its correction's deployment is under way (completed by
#: app.services.checks.frame_recheck).
DEPLOYMENT_FOLLOWS = "; its deployment to the controller follows"


def check_options(data: FrameCheckCreate) -> None:
    """422 /invalid-options for `deploy` without a correction, or a robot-wide scope that
    would correct nothing."""
    if data.deploy is not None and data.correct == "never":
        raise InvalidInput(
            "invalid-options",
            '"deploy" applies to a correction: send "correct": "within_limits" with it, '
            "or leave deploy out",
            loc=("body", "deploy"),
        )
    names = [t.fiducial for t in data.touches]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise InvalidInput(
                "invalid-options",
                f"touch {i + 1} names fiducial {name!r} again (touch {names.index(name) + 1} "
                "did): touch each fiducial once, or name the one touched",
                loc=("body", "touches", i, "fiducial"),
            )


@dataclass(frozen=True)
class _Fiducials:
    names: list[str]
    nominal_mm: FloatArray  # (K, 3) frame coordinates


def stored_fiducials(session: Session, frame_id: str) -> _Fiducials:
    """The fiducials the calibration behind the frame's active version kept
    (app.services.frames.fiducials), with their coordinates in the frame (a correction
    carries the frame and keeps naming that calibration, so they hold in it too). 422 when
    it kept none."""
    kept = list_fiducials(session, frame_id=frame_id).items
    if not kept:
        raise InvalidInput(
            "unknown-reference",
            f"frame {frame_id} has no stored fiducials to touch again: its active version "
            "was not calibrated from touches (a frame entered by hand keeps none); calibrate "
            f"it first (POST /v1/frames/{frame_id}/calibrations)",
            loc=("body", "touches"),
        )
    return _Fiducials(
        [f.name for f in kept], np.array([f.nominal_mm for f in kept], dtype=np.float64)
    )


def _pointer(
    session: Session, tool_id: str, robot_id: str
) -> tuple[Tool, FloatArray, FloatArray, int]:
    """The pointer tool of the frame's robot: (tool, TCP mm, its covariance mm^2, version)."""
    tool = session.get(Tool, tool_id)
    if tool is None or tool.archived_at is not None or tool.robot_id != robot_id:
        raise InvalidInput(
            "unknown-reference",
            f"robot {robot_id} has no live tool {tool_id}: touch the fiducials with a pointer "
            "tool of the frame's robot",
            loc=("body", "tool_id"),
        )
    frame = active_frame(session, tool)
    if frame is None or frame.version is None:
        raise InvalidInput(
            "unknown-reference",
            f"pointer tool {tool_id} has no active TCP version: its TCP is what turns each "
            f"touch into a point; calibrate it first (POST /v1/tools/{tool_id}/calibrations)",
            loc=("body", "tool_id"),
        )
    cov = frame.covariance_mm2 if frame.covariance_mm2 is not None else np.zeros((3, 3))
    return tool, frame.position_mm, np.asarray(cov, dtype=np.float64), frame.version


def far_mm(tolerance: FrameTolerance) -> float:
    """How far from its stored place a touch may be and still be the fiducial it names."""
    return FAR_FACTOR * tolerance.max_correction_mm + FAR_MARGIN_MM


@dataclass(frozen=True)
class _Measured:
    """A check measured, nothing written: the frame and its active version, the fiducials
    touched (names, stored base positions), the shift and the pointer it was touched with."""

    frame: Frame
    version: int
    calibration_id: str | None
    pose: Pose
    names: list[str]
    stored_mm: FloatArray
    shift: Shift
    pointer: FramePointer
    limits: FrameTolerance

    @property
    def worst(self) -> int:
        return int(np.argmax(self.shift.distances_mm))

    @property
    def largest_mm(self) -> float:
        return float(self.shift.distances_mm[self.worst])


def _measure(session: Session, *, frame_id: str, data: FrameCheckCreate) -> _Measured:
    """The shift from the frame's stored fiducials to the touches; a touch far from the
    fiducial it names refused first (422 at body.touches[i].fiducial)."""
    frame = session.get(Frame, frame_id)
    assert frame is not None  # locked by the caller
    robot = get_robot(session, frame.robot_id)
    active = lifecycle.active_version_row(session, FRAME, frame)  # 404 /no-active-version
    pose = Pose.of(active.position_mm, active.quaternion)
    fiducials = stored_fiducials(session, frame_id)
    tool, tcp_mm, tcp_cov, tcp_version = _pointer(session, data.tool_id, robot.id)
    limits = frame_tolerance(frame.tolerance)
    stored_base = fiducials.nominal_mm @ pose.rotation.T + pose.origin_mm
    names = [t.fiducial for t in data.touches]
    with located_in("body"):
        rotations, flanges = parse_poses_with(
            robot.kinematics,
            data.format,
            [t.pose for t in data.touches],
            data.units,
            loc=("touches",),
        )
        points = touch_points(rotations, flanges, tcp_mm)
        check_near(names, stored_base, fiducials.names, points, far_mm(limits))
        chosen = stored_base[[fiducials.names.index(n) for n in names]]
        shift = shift_from_fiducials(
            chosen, pose.rotation, points, rotations, tcp_cov, touch_noise_mm=limits.touch_noise_mm
        )
    pointer = FramePointer(
        tool_id=tool.id,
        version=tcp_version,
        tcp_sigma_mm=[float(s) for s in np.sqrt(np.clip(np.diag(tcp_cov), 0.0, None))],
    )
    return _Measured(
        frame, active.version, active.calibration_id, pose, names, chosen, shift, pointer, limits
    )


def check_and_correct(
    session: Session,
    *,
    frame_id: str,
    data: FrameCheckCreate,
    actor: Principal,
    deploying: bool,
    by_hand: str | None = None,
) -> FrameCheck:
    """The check recorded and, when due, the correction stored and activated (the check's
    event first: check -> version -> activation in the trail). `by_hand`: why no deployment
    can be made to the robot's controller (it writes no frame), said in the summary."""
    m = _measure(session, frame_id=frame_id, data=data)
    verdict = _verdict(m.largest_mm, m.limits, data)
    correction = None
    if verdict == "corrected":  # numbered now: the check is recorded before what it changes
        next_version = lifecycle.lock(session, FRAME, frame_id).next_version
        correction = FrameCorrection(version=next_version, previous_version=m.version)
    result = _document(m, data, verdict, correction, actor)
    result.differs_from = _differs_from(session, m.frame, m.shift, m.stored_mm, m.limits)
    result.summary = summary(result, m, deploying=deploying, asked=deploys(data), by_hand=by_hand)
    _record(session, result, m, actor)
    if correction is None:
        return result
    version, _ = correct_frame(
        session,
        frame_id=frame_id,
        pose=m.pose,
        shift=m.shift,
        checked_version=m.version,
        calibration_id=m.calibration_id,
        reason=data.reason,
        actor=actor,
        check_id=result.id,
    )
    assert version == correction.version
    if data.scope == "robot":
        correction.moved = correct_robot(
            session,
            robot_id=m.frame.robot_id,
            checked_frame_id=frame_id,
            shift=m.shift,
            reason=data.reason,
            actor=actor,
            check_id=result.id,
        )
        result.summary = summary(
            result, m, deploying=deploying, asked=deploys(data), by_hand=by_hand
        )
    return result


def _document(
    m: _Measured,
    data: FrameCheckCreate,
    verdict: FrameCheckVerdict,
    correction: FrameCorrection | None,
    actor: Principal,
) -> FrameCheck:
    return FrameCheck(
        id=new_id(),
        frame_id=m.frame.id,
        robot_id=m.frame.robot_id,
        version=m.version,
        scope=data.scope,
        tool=m.pointer,
        deviations=[
            FiducialDeviation(
                fiducial=name,
                deviation_mm=[float(v) for v in d],
                distance_mm=float(np.linalg.norm(d)),
                words=_deviation_words(name, d),
            )
            for name, d in zip(m.names, m.shift.deviations_mm, strict=True)
        ],
        shift=_shift_out(m.shift),
        verdict=verdict,
        correction=correction,
        summary="",
        created_at=utcnow(),
        created_by=actor.name,
    )


def _verdict(
    largest_mm: float, limits: FrameTolerance, data: FrameCheckCreate
) -> FrameCheckVerdict:
    """Judged at the fiducials: within check_mm it holds; past it, corrected when asked and
    none is past max_correction_mm; else it needs recalibrating (nothing changes)."""
    if largest_mm <= limits.check_mm:
        return "within_tolerance"
    if data.correct == "within_limits" and largest_mm <= limits.max_correction_mm:
        return "corrected"
    return "needs_recalibration"


def deploys(data: FrameCheckCreate) -> bool:
    return data.correct == "within_limits" and data.deploy is not False


def _deviation_words(name: str, d: FloatArray) -> str:
    axes = ", ".join(f"{v:+.2f} {a}" for v, a in zip(d, "xyz", strict=True))
    return f"fiducial {name!r} moved {float(np.linalg.norm(d)):.2f} mm ({axes} in the frame's axes)"


def _shift_out(shift: Shift) -> FrameShift:
    fit = shift.fit
    used = np.asarray(fit.used, dtype=bool)
    residuals = np.asarray(fit.residuals_mm, dtype=float)[used]
    return FrameShift(
        position_mm=[float(v) for v in shift.translation_mm],
        angle_deg=shift.angle_deg,
        axis=[float(v) for v in shift.axis],
        position_sigma_mm=[float(s) for s in fit.position_sigma_mm],
        angle_sigma_deg=[float(s) for s in fit.angle_sigma_deg],
        rms_mm=float(np.sqrt(np.mean(residuals**2))) if residuals.size else 0.0,
    )


def summary(
    result: FrameCheck, m: _Measured, *, deploying: bool, asked: bool, by_hand: str | None = None
) -> str:
    """The check in a sentence or two: how far the fiducials moved, and what was done."""
    shift, limits, largest_mm, worst = result.shift, m.limits, m.largest_mm, m.names[m.worst]
    moved = (
        f"the frame moved {np.linalg.norm(shift.position_mm):.2f} mm and {shift.angle_deg:.3f} "
        f"deg; its largest deviation is {largest_mm:.2f} mm at fiducial {worst!r}"
    )
    if result.verdict == "within_tolerance":
        said = f"{moved}, within check_mm {limits.check_mm:g} mm: nothing to correct"
    elif result.verdict == "needs_recalibration":
        if largest_mm > limits.max_correction_mm:
            said = (
                f"{moved}, beyond max_correction_mm {limits.max_correction_mm:g} mm: nothing was "
                f"changed; recalibrate the frame (POST /v1/frames/{result.frame_id}/calibrations)"
            )
        else:
            said = (
                f"{moved}, past check_mm {limits.check_mm:g} mm: nothing was changed; resend "
                'with "correct": "within_limits" to correct it, or recalibrate the frame'
            )
    else:
        assert result.correction is not None
        others = result.correction.moved
        frames = sum(1 for m in others if m.kind == "frame")
        points = len(others) - frames
        said = (
            f"{moved}: corrected as version {result.correction.version} (was "
            f"{result.correction.previous_version}), active"
        )
        if result.scope == "robot":
            said += (
                f"; the robot moved: {frames} other frame{'s' if frames != 1 else ''} and "
                f"{points} reference point{'s' if points != 1 else ''} corrected by the same "
                "shift"
            )
        if deploying:
            said += DEPLOYMENT_FOLLOWS
        elif asked and by_hand is not None:
            said += f"; no deployment was made: {by_hand}"
        elif asked:
            said += (
                "; not deployed: the robot has no controller: load the frame's file (GET "
                f"/v1/frames/{result.frame_id}/frame, Accept: text/plain), or connect it (PUT "
                f"/v1/robots/{result.robot_id}/controller) and deploy (POST "
                f"/v1/frames/{result.frame_id}/deployments)"
            )
        else:
            said += (
                '; not deployed ("deploy": false): deploy the new version (POST '
                f"/v1/frames/{result.frame_id}/deployments) before the robot runs with it"
            )
    if result.differs_from:
        said += (
            f"; this shift differs from the one found at frame(s) "
            f"{', '.join(result.differs_from)} of this robot within the hour: one fixture "
            "moved, not the robot (not averaged)"
        )
    return said


def _differs_from(
    session: Session,
    frame: Frame,
    shift: Shift,
    stored_mm: FloatArray,
    limits: FrameTolerance,
) -> list[str]:
    """Other frames of the robot checked within the hour whose shift would move this frame's
    fiducials more than check_mm away from where this shift moves them."""
    since = utcnow() - SAME_MOVE_WITHIN
    rows = session.execute(
        select(AuditEvent.frame_id, AuditEvent.details)
        .where(
            AuditEvent.robot_id == frame.robot_id,
            AuditEvent.action == FRAME_CHECK_ACTION,
            AuditEvent.frame_id != frame.id,
            AuditEvent.at >= since,
        )
        .order_by(AuditEvent.id)
    ).all()
    ours = stored_mm @ shift.rotation.T + shift.translation_mm
    differs: list[str] = []
    for other_id, details in rows:
        theirs_shift = (details or {}).get("shift")
        if not isinstance(theirs_shift, dict) or other_id is None or other_id in differs:
            continue
        rotation = Rotation.from_rotvec(theirs_shift["rotvec_rad"]).as_matrix()
        theirs = stored_mm @ rotation.T + np.asarray(theirs_shift["position_mm"], dtype=float)
        if float(np.linalg.norm(theirs - ours, axis=1).max()) > limits.check_mm:
            differs.append(str(other_id))
    return differs


def _record(session: Session, result: FrameCheck, m: _Measured, actor: Principal) -> None:
    """The check in the audit trail (`frame.check`: the fleet's check_failed and the drift
    trend read it back) and, when nothing changes, the frame's trend refitted with it (a
    correction's new version refits it)."""
    deviation = [float(v) for v in m.shift.deviations_mm[m.worst]]
    correction = result.correction
    details: JsonObject = {
        "check_id": result.id,
        "version": result.version,
        "scope": result.scope,
        "deviation_mm": deviation,
        "distance_mm": m.largest_mm,
        "check_mm": m.limits.check_mm,
        "within_tolerance": result.verdict == "within_tolerance",
        "verdict": result.verdict,
        "shift": shift_details(m.shift),
        "summary": result.summary,
        "correction": None
        if correction is None
        else correction.model_dump(mode="json", include={"version", "previous_version"}),
    }
    audit.record(
        session,
        actor=actor,
        action=FRAME_CHECK_ACTION,
        resource_type=FRAME.kind,
        resource_id=m.frame.id,
        robot_id=m.frame.robot_id,
        about={FRAME.key: m.frame.id},
        version=result.version,
        details=details,
    )
    if correction is None:
        locked = lifecycle.lock(session, FRAME, m.frame.id)
        pending = drift.Point(result.created_at, deviation)
        fitted = drift.fit_drift(session, FRAME, locked, pending)
        drift.store_drift(session, FRAME, m.frame.id, fitted)
