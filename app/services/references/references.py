"""Reference points (fixed points in a robot's base frame) and laser devices, per robot."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.arrays import FloatArray
from app.errors import Conflict, InvalidInput, NotFound, located_in
from app.helpers.pagination import paginate
from app.helpers.tolerance import effective_tolerance
from app.kinematics.poses import one_pose
from app.schemas.common import Units
from app.schemas.references import ReferencePointCreate
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.robots.robots import get_robot
from app.services.tools.tools import tool_named_in_body
from app.services.touches.diagnosis import (
    implausible_flanges,
    one_touch_fits,
    refuse_mix_up,
    refusing_mix_ups,
)
from app.services.touches.tool_frames import active_frame, parse_poses_with
from app.solvers.reference import reference_point_from_touch
from app.storage.models import LaserDevice, ReferencePoint, new_id
from app.words import PoseFormat


def ensure_name_free(
    session: Session,
    model: type[ReferencePoint] | type[LaserDevice],
    *,
    robot_id: str,
    name: str,
    loc: tuple[str, ...] = ("body", "name"),
) -> None:
    """409 naming `loc` when the robot already has a `model` row called `name`."""
    taken = session.scalars(
        select(model.id).where(model.robot_id == robot_id, model.name == name)
    ).first()
    if taken:
        what = "reference point" if model is ReferencePoint else "laser device"
        raise Conflict(
            f"robot {robot_id} already has a {what} named {name!r}",
            loc=loc,
            msg="already taken",
        )


def ensure_reference_name_free(
    session: Session, *, robot_id: str, name: str, loc: tuple[str, ...] = ("body", "name")
) -> None:
    """409 when the robot already has a reference point called `name`."""
    ensure_name_free(session, ReferencePoint, robot_id=robot_id, name=name, loc=loc)


def create_reference_point(
    session: Session,
    *,
    robot_id: str,
    name: str,
    position_mm: Sequence[float],
    covariance_mm2: Sequence[Sequence[float]] | None,
    source: str,
    calibration_id: str | None,
    actor: Principal,
) -> ReferencePoint:
    """Store a reference point (name unique per robot)."""
    get_robot(session, robot_id)
    ensure_reference_name_free(session, robot_id=robot_id, name=name)
    row = ReferencePoint(
        id=new_id(),
        robot_id=robot_id,
        name=name,
        position_mm=[float(v) for v in position_mm],
        covariance_mm2=[[float(v) for v in r] for r in covariance_mm2] if covariance_mm2 else None,
        source=source,
        calibration_id=calibration_id,
        created_by=actor.name,
    )
    return audit.add_created(
        session,
        row,
        actor=actor,
        action="reference_point.create",
        resource_type="reference_point",
        robot_id=robot_id,
        details={"name": name, "source": source, "position_mm": row.position_mm},
    )


RobotRow = TypeVar("RobotRow", ReferencePoint, LaserDevice)


def list_robot_rows(
    session: Session, model: type[RobotRow], *, robot_id: str, limit: int, cursor: str | None
) -> tuple[Sequence[RobotRow], str | None]:
    """One page of a robot's reference points or laser devices."""
    get_robot(session, robot_id)
    stmt = select(model).where(model.robot_id == robot_id)
    return paginate(
        session, stmt, created_col=model.created_at, id_col=model.id, limit=limit, cursor=cursor
    )


def register_reference_point(
    session: Session, *, robot_id: str, data: ReferencePointCreate, actor: Principal
) -> ReferencePoint:
    """A reference point entered as numbers, or touched by a tool whose active TCP is trusted."""
    robot = get_robot(session, robot_id)
    if data.touch is None:
        assert data.position_mm is not None
        return create_reference_point(
            session,
            robot_id=robot_id,
            name=data.name,
            position_mm=data.position_mm,
            covariance_mm2=data.covariance_mm2,
            source="numeric",
            calibration_id=None,
            actor=actor,
        )
    touch = data.touch
    tool = tool_named_in_body(
        session, touch.tool_id, robot_id=robot_id, loc=("body", "touch", "tool_id")
    )
    frame = active_frame(session, tool)
    if frame is None:
        raise InvalidInput(
            "unknown-reference",
            f"tool {tool.id} has no active TCP to touch the point with",
            loc=("body", "touch", "tool_id"),
        )

    def read(fmt: PoseFormat, units: Units | None) -> tuple[FloatArray, FloatArray]:
        with one_pose(("touch", "pose")):
            pose = [touch.pose]
            return parse_poses_with(robot.kinematics, fmt, pose, units, loc=("touch", "pose"))

    def flange(fmt: PoseFormat, units: Units | None) -> FloatArray:
        return read(fmt, units)[1]

    # One touch has no redundancy: only whether it reads, and where the flange is, tell a
    # mix-up apart.
    if implausible_flanges(flange, touch.format, touch.units):
        refuse_mix_up(
            touch.format,
            touch.units,
            one_touch_fits,
            flange,
            as_given=None,
            near_base=True,
            within=("body", "touch"),
            poses_field="pose",
        )
    with (
        refusing_mix_ups(
            touch.format,
            touch.units,
            one_touch_fits,
            flange,
            within=("body", "touch"),
            poses_field="pose",
        ),
        located_in("body"),
    ):
        rotations, positions = read(touch.format, touch.units)
        point, covariance = reference_point_from_touch(
            tcp_mm=frame.position_mm,
            tcp_covariance_mm2=frame.covariance_mm2,
            rotation=rotations[0],
            position_mm=positions[0],
            touch_noise_mm=effective_tolerance(tool.tolerance).touch_noise_mm,
        )
    return create_reference_point(
        session,
        robot_id=robot_id,
        name=data.name,
        position_mm=point.tolist(),
        covariance_mm2=covariance.tolist(),
        source=f"touch:{tool.id}:v{frame.version}",
        calibration_id=None,
        actor=actor,
    )


def get_reference_point(session: Session, *, robot_id: str, point_id: str) -> ReferencePoint:
    """One reference point of a robot, or 404."""
    get_robot(session, robot_id)
    row = session.get(ReferencePoint, point_id)
    if row is None or row.robot_id != robot_id:
        raise NotFound(f"robot {robot_id} has no reference point {point_id}")
    return row


def list_reference_points(
    session: Session, *, robot_id: str, limit: int, cursor: str | None
) -> tuple[Sequence[ReferencePoint], str | None]:
    """One page of a robot's reference points, oldest first."""
    return list_robot_rows(session, ReferencePoint, robot_id=robot_id, limit=limit, cursor=cursor)
