"""TCP checks: touch a stored reference point with the active TCP and measure the drift.

A check never changes the active TCP; it is recorded in the audit trail either way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from sqlalchemy.orm import Session

from app.arrays import FloatArray
from app.errors import located_in
from app.helpers.tolerance import effective_tolerance
from app.jsontypes import JsonArray, JsonObject
from app.methods.base import ActiveFrame
from app.schemas.common import Pose, Units
from app.schemas.references import CheckCreate, CheckResult, CheckTouch
from app.security.auth import Principal, transaction_for
from app.services.audit import writes as audit
from app.services.calibrations.verdict import check_summary
from app.services.controllers import capture
from app.services.references.references import get_reference_point
from app.services.robots.robots import get_robot
from app.services.tools.drift import Point, refresh_drift
from app.services.tools.tools import get_tool
from app.services.tools.versions import active_version_row, lock_tool
from app.services.touches.diagnosis import (
    Fit,
    implausible_flanges,
    refuse_mix_up,
    refusing_mix_ups,
)
from app.services.touches.tool_frames import frame_of, parse_poses_with
from app.solvers.reference import TcpDeviation, check_tcp
from app.storage.models import ReferencePoint, Tool, utcnow
from app.words import CHECK_ACTION, PoseFormat


@dataclass(frozen=True)
class Captured:
    """A check's one touch as read from the controller: the reading (audited) and the
    pose it was converted to."""

    capture: capture.Capture
    pose: Pose


def capture_touch(tool_id: str, data: CheckCreate, actor: Principal) -> Captured:
    """The one touch of a captured check: what is refused before the controller is read is
    refused first (no active version, no such point), then one still read with no
    transaction open."""
    with transaction_for(actor, write=False) as session:
        tool = get_tool(session, tool_id)
        active_version_row(session, tool)
        get_reference_point(session, robot_id=tool.robot_id, point_id=data.reference_point_id)
        settings = capture.settings_for_robot(session, tool.robot_id)
    captured = capture.read_still(settings, robot_id=tool.robot_id)
    pose = capture.pose_in_format(captured, CAPTURE_FORMAT, None, loc=("body", "capture"))
    return Captured(captured, pose)


def as_typed(data: CheckCreate, captured: Captured) -> CheckCreate:
    """The captured check as the typed one it is checked as."""
    return data.model_copy(
        update={"capture": None, "format": CAPTURE_FORMAT, "poses": [captured.pose]}
    )


#: The format a captured check touch is converted to (any would do: it is read back at once).
CAPTURE_FORMAT: PoseFormat = "matrix"


def run_check(
    session: Session,
    *,
    tool_id: str,
    data: CheckCreate,
    actor: Principal,
    captured: capture.Capture | None = None,
) -> CheckResult:
    """Deviation of the active TCP at a reference point, against the tool's check_mm,
    recorded. `captured`: the controller's reading the one pose was converted from (audited)."""
    measured = measure(session, tool_id=tool_id, data=data, actor=actor)
    record(session, measured, actor, captured)
    return measured.result


@dataclass(frozen=True)
class Measured:
    """A check measured, not yet recorded: the tool, the version and point it was measured
    with, and the result."""

    tool: Tool
    frame: ActiveFrame
    point: ReferencePoint
    result: CheckResult


def measure(session: Session, *, tool_id: str, data: CheckCreate, actor: Principal) -> Measured:
    """The check's result, with nothing written (typed touches: `format` and `poses`)."""
    tool = get_tool(session, tool_id)
    robot = get_robot(session, tool.robot_id)
    frame = frame_of(session, active_version_row(session, tool))  # 404 /no-active-version
    point = get_reference_point(session, robot_id=robot.id, point_id=data.reference_point_id)
    limit = effective_tolerance(tool.tolerance).check_mm
    fmt, poses = data.format, data.poses
    # typed, or captured and converted
    assert fmt is not None
    assert poses is not None
    touches = _measured_touches(
        robot.kinematics,
        Typed(fmt, poses, data.units),
        tcp_mm=frame.position_mm,
        reference_mm=point.position_mm,
        limit=limit,
    )
    assert frame.version is not None  # a stored version's frame
    result = _check_result(
        tool.id, version=frame.version, point_id=point.id, touches=touches, limit=limit, actor=actor
    )
    return Measured(tool, frame, point, result)


def record(
    session: Session, measured: Measured, actor: Principal, captured: capture.Capture | None
) -> None:
    """The check in the audit trail, and the drift trend it is the newest point of."""
    _record(session, measured.tool, measured.result, actor, captured)
    _refresh_trend(session, measured.tool.id, measured.result)


@dataclass(frozen=True)
class Typed:
    """A check's touches as poses in a format."""

    format: PoseFormat
    poses: Sequence[Pose]
    units: Units | None


def _measured_touches(
    kinematics: JsonObject | None,
    data: Typed,
    *,
    tcp_mm: FloatArray,
    reference_mm: JsonArray,
    limit: float,
) -> list[TcpDeviation]:
    """Each touch's deviation from the reference point; when the worst is past the limit or
    the flanges sit implausibly near the base, a clearly better reading of the poses'
    format or units is refused as a mix-up (app.services.touches.diagnosis)."""

    def positions(fmt: PoseFormat, units: Units | None) -> FloatArray:
        return parse_poses_with(kinematics, fmt, data.poses, units, loc=("poses",))[1]

    def measure(fmt: PoseFormat, units: Units | None) -> list[TcpDeviation]:
        rotations, flanges = parse_poses_with(kinematics, fmt, data.poses, units, loc=("poses",))
        return [
            check_tcp(tcp_mm=tcp_mm, rotation=R, position_mm=f, reference_mm=reference_mm)
            for R, f in zip(rotations, flanges, strict=True)
        ]

    def attempt(fmt: PoseFormat, units: Units) -> Fit:
        worst = max(t.distance_mm for t in measure(fmt, units))
        return Fit(float(worst), float(worst) <= limit)

    with refusing_mix_ups(data.format, data.units, attempt, positions), located_in("body"):
        touches = measure(data.format, data.units)
    worst_mm = max(float(t.distance_mm) for t in touches)
    near_base = implausible_flanges(positions, data.format, data.units)
    if worst_mm > limit or near_base:
        as_given = Fit(worst_mm, good=False)
        refuse_mix_up(
            data.format, data.units, attempt, positions, as_given=as_given, near_base=near_base
        )
    return touches


def _floats(values: FloatArray) -> list[float]:
    return [float(v) for v in values]


def _check_result(
    tool_id: str,
    *,
    version: int,
    point_id: str,
    touches: list[TcpDeviation],
    limit: float,
    actor: Principal,
) -> CheckResult:
    # The headline figures are the worst touch's, so they are the ones the verdict rests on:
    # a bent tool seen from several orientations would average towards zero.
    worst = max(touches, key=lambda t: t.distance_mm)
    mean_base = np.mean([t.deviation_base_mm for t in touches], axis=0)
    return CheckResult(
        tool_id=tool_id,
        version=version,
        reference_point_id=point_id,
        deviation_mm=_floats(worst.deviation_base_mm),
        deviation_flange_mm=_floats(worst.deviation_flange_mm),
        distance_mm=float(worst.distance_mm),
        mean_deviation_mm=_floats(mean_base),
        check_mm=limit,
        within_tolerance=float(worst.distance_mm) <= limit,
        verdict="within_tolerance" if float(worst.distance_mm) <= limit else "out_of_tolerance",
        summary=check_summary(
            distance_mm=float(worst.distance_mm),
            deviation_flange_mm=_floats(worst.deviation_flange_mm),
            version=version,
            n_touches=len(touches),
            check_mm=limit,
        ),
        touches=[
            CheckTouch(
                deviation_mm=_floats(t.deviation_base_mm),
                deviation_flange_mm=_floats(t.deviation_flange_mm),
                distance_mm=float(t.distance_mm),
            )
            for t in touches
        ],
        checked_at=utcnow(),
        checked_by=actor.name,
    )


#: What a check's audit event keeps of its result (GET .../checks reads them back).
_AUDITED = {
    "version",
    "reference_point_id",
    "deviation_mm",
    "distance_mm",
    "check_mm",
    "within_tolerance",
    "deviation_flange_mm",
    "summary",
    "verdict",
    "correction",
}


def _record(
    session: Session,
    tool: Tool,
    result: CheckResult,
    actor: Principal,
    captured: capture.Capture | None,
) -> None:
    details = result.model_dump(mode="json", include=_AUDITED)
    # Where the touch came from, and what the controller printed for a captured one.
    details["sources"] = [capture.typed_touch()] * len(result.touches)
    if captured is not None:
        details["sources"] = [captured.touch_record()]
    audit.record(
        session,
        actor=actor,
        action=CHECK_ACTION,  # read back by the drift trend and the fleet
        resource_type="tool",
        resource_id=tool.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        version=result.version,
        details=details,
    )


def _refresh_trend(session: Session, tool_id: str, result: CheckResult) -> None:
    """The check is the trend's newest point; the tool's lock orders concurrent checks, so
    each one's trend reads the ones committed before it."""
    locked = lock_tool(session, tool_id)
    pending = Point(result.checked_at, result.deviation_flange_mm)
    refresh_drift(
        session,
        locked,
        pending_check=pending if locked.active_version == result.version else None,
    )
