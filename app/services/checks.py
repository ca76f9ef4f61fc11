"""TCP checks: touch a stored reference point with the active TCP and measure the drift.

A check never changes the active TCP; it is recorded in the audit trail either way.
"""

from __future__ import annotations

import numpy as np
from sqlalchemy.orm import Session

from app.auth import Principal
from app.errors import located_in
from app.helpers.tolerance import effective_tolerance
from app.models import utcnow
from app.schemas.references import CheckCreate, CheckResult, CheckTouch
from app.services import audit
from app.services.frames import frame_of, parse_poses_with
from app.services.references import get_reference_point
from app.services.robots import get_robot
from app.services.tools import get_tool
from app.services.versions import active_version_row
from app.solvers.reference import check_tcp


def run_check(
    session: Session,
    *,
    tool_id: str,
    data: CheckCreate,
    actor: Principal,
) -> CheckResult:
    """Deviation of the active TCP at a reference point, against the tool's check_mm."""
    tool = get_tool(session, tool_id)
    robot = get_robot(session, tool.robot_id)
    frame = frame_of(session, active_version_row(session, tool))  # 404 /no-active-version
    point = get_reference_point(session, robot_id=robot.id, point_id=data.reference_point_id)
    with located_in("body"):
        rotations, positions = parse_poses_with(
            robot.kinematics, data.format, data.poses, data.units, loc=("poses",)
        )
    touches = [
        check_tcp(
            tcp_mm=frame.position_mm, rotation=R, position_mm=f, reference_mm=point.position_mm
        )
        for R, f in zip(rotations, positions, strict=True)
    ]
    # The headline figures are the worst touch's, so they are the ones the verdict rests on:
    # a bent tool seen from several orientations would average towards zero.
    worst = max(touches, key=lambda t: t.distance_mm)
    mean_base = np.mean([t.deviation_base_mm for t in touches], axis=0)
    limit = effective_tolerance(tool.tolerance).check_mm
    within = float(worst.distance_mm) <= limit
    assert frame.version is not None  # a stored version's frame
    result = CheckResult(
        tool_id=tool.id,
        version=frame.version,
        reference_point_id=point.id,
        deviation_mm=[float(v) for v in worst.deviation_base_mm],
        deviation_flange_mm=[float(v) for v in worst.deviation_flange_mm],
        distance_mm=float(worst.distance_mm),
        mean_deviation_mm=[float(v) for v in mean_base],
        check_mm=limit,
        within_tolerance=within,
        touches=[
            CheckTouch(
                deviation_mm=[float(v) for v in t.deviation_base_mm],
                deviation_flange_mm=[float(v) for v in t.deviation_flange_mm],
                distance_mm=float(t.distance_mm),
            )
            for t in touches
        ],
        checked_at=utcnow(),
        checked_by=actor.name,
    )
    audit.record(
        session,
        actor=actor,
        action="tool.check",
        resource_type="tool",
        resource_id=tool.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        details=result.model_dump(
            mode="json",
            include={
                "version",
                "reference_point_id",
                "deviation_mm",
                "distance_mm",
                "check_mm",
                "within_tolerance",
            },
        ),
    )
    return result
