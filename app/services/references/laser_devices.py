"""Laser devices per robot: beam geometry entered as numbers or taught with a trusted tool."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy.orm import Session

from app.errors import InvalidInput, NotFound, located_in
from app.methods.laser import sweeps_from
from app.schemas.references import LaserDeviceCreate
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.references.references import ensure_name_free, list_robot_rows
from app.services.robots.robots import get_robot
from app.services.tools.tools import tool_named_in_body
from app.services.touches.tool_frames import active_frame, parse_poses_with
from app.solvers.laser import teach_device
from app.storage.models import LaserDevice, new_id


def create_laser_device(
    session: Session, *, robot_id: str, data: LaserDeviceCreate, actor: Principal
) -> LaserDevice:
    """Store a device; when taught, solve its geometry from a trusted tool's sweeps."""
    robot = get_robot(session, robot_id)
    ensure_name_free(session, LaserDevice, robot_id=robot_id, name=data.name)
    if data.teach is None:
        assert data.beam_a_y_mm is not None and data.beam_b_x_mm is not None  # noqa: PT018
        assert data.plane_z_mm is not None
        row = LaserDevice(
            id=new_id(),
            robot_id=robot_id,
            name=data.name,
            beam_a_y_mm=data.beam_a_y_mm,
            beam_b_x_mm=data.beam_b_x_mm,
            plane_z_mm=data.plane_z_mm,
            source="numeric",
            details=None,
            created_by=actor.name,
        )
    else:
        teach = data.teach
        tool = tool_named_in_body(
            session, teach.tool_id, robot_id=robot_id, loc=("body", "teach", "tool_id")
        )
        frame = active_frame(session, tool)
        if frame is None:
            raise InvalidInput(
                "unknown-reference",
                f"tool {teach.tool_id} is not a tool of robot {robot_id} with an active TCP; "
                "teach the device with a tool whose TCP is trusted",
                loc=("body", "teach", "tool_id"),
            )
        axis = Rotation.from_quat(frame.quaternion, scalar_first=True).apply([0.0, 0.0, 1.0])
        with located_in("body", "teach"):
            rotations, _ = parse_poses_with(
                robot.kinematics, teach.format, teach.poses, teach.units, loc=("poses",)
            )
            device, fit = teach_device(
                flange_rotation=rotations[0],
                sweeps=sweeps_from(teach.sweeps),
                descent_mm=teach.descent_mm,
                tcp_mm=frame.position_mm,
                tool_axis_flange=np.asarray(axis),
                trigger_noise_mm=teach.trigger_noise_mm,
            )
        row = LaserDevice(
            id=new_id(),
            robot_id=robot_id,
            name=data.name,
            beam_a_y_mm=device.beam_a_y_mm,
            beam_b_x_mm=device.beam_b_x_mm,
            plane_z_mm=device.plane_z_mm,
            source="taught",
            details={
                "tool_id": tool.id,
                "tool_version": frame.version,
                "residuals_mm": list(fit.residuals_mm),
                "sigma_mm": list(fit.sigma_mm),
                "sigma_source": fit.sigma_source,
                "widths_mm": list(fit.widths_mm),
                "warnings": list(fit.warnings),
            },
            created_by=actor.name,
        )
    return audit.add_created(
        session,
        row,
        actor=actor,
        action="laser_device.create",
        resource_type="laser_device",
        robot_id=robot_id,
        details={"name": row.name, "source": row.source},
    )


def get_laser_device(session: Session, *, robot_id: str, device_id: str) -> LaserDevice:
    """One laser device of a robot, or 404."""
    get_robot(session, robot_id)
    row = session.get(LaserDevice, device_id)
    if row is None or row.robot_id != robot_id:
        raise NotFound(f"robot {robot_id} has no laser device {device_id}")
    return row


def list_laser_devices(
    session: Session, *, robot_id: str, limit: int, cursor: str | None
) -> tuple[Sequence[LaserDevice], str | None]:
    """One page of a robot's laser devices, oldest first."""
    return list_robot_rows(session, LaserDevice, robot_id=robot_id, limit=limit, cursor=cursor)
