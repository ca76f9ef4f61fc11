"""Touches straight from the controller (contract v1.3): where the robot's flange is, read
from its controller, kept only when the robot stood still.

The controller already computes the flange from its joint angles; reading it spares the
person at the cell from copying six numbers a touch off the pendant, where unit and
convention mix-ups are born. One connector session reads the pose twice, at least
`STILL_GAP_S` apart: a robot still jogging (or drifting under a brake) between the reads
would give a touch that belongs to no pose, so readings further apart than `STILL_MM` or
`STILL_DEG` are refused (409 /robot-moving) and nothing is kept. The controller's I/O runs
with no database transaction open (as deployments do): a read transaction gathers how to
reach the controller, the connector reads, and the caller then writes in a transaction of
its own.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy.orm import Session

from app.errors import (
    InvalidInput,
    NoController,
    NoControllerSet,
    RobotMoving,
)
from app.helpers.frame_deviation import frame_deviation, within
from app.jsontypes import JsonObject
from app.kinematics.poses import pose_to_format, resolve_units
from app.schemas.common import Pose, Units
from app.schemas.controllers import ControllerPose
from app.schemas.results import TouchSource
from app.security.auth import Principal, transaction_for
from app.services.controllers.failures import controller_problem
from app.services.robots.connection import get_controller, settings_of
from app.services.robots.live_tool import live_tool_matches, live_tool_out
from app.storage.models import utcnow
from app.vendors.connector import (
    ControllerError,
    ControllerSettings,
    Frame,
    PoseReading,
)
from app.vendors.registry import connect
from app.words import PoseFormat, ProtocolName, TouchOrigin

#: The two reads of one capture are at least this far apart (s).
STILL_GAP_S = 0.1
#: A robot whose flange moved more than these between the two reads is moving.
STILL_MM = 0.01
STILL_DEG = 0.01


@dataclass(frozen=True)
class Capture:
    """One still reading of the robot's pose, as a touch keeps it."""

    robot_id: str
    protocol: ProtocolName
    reading: PoseReading
    read_at: datetime

    def rotation_position(self) -> tuple[Rotation, np.ndarray]:
        """The flange (R, t mm) in the robot's base frame."""
        w, x, y, z = self.reading.flange.quaternion
        return Rotation.from_quat([x, y, z, w]), np.asarray(self.reading.flange.position_mm)

    def touch_record(self) -> JsonObject:
        """The touch's source as a session stores it, with what the controller printed."""
        source: TouchOrigin = "controller"
        return {
            "source": source,
            "read_at": self.read_at.isoformat().replace("+00:00", "Z"),
            "protocol": self.protocol,
            "readings": dict(self.reading.readings),
        }


def typed_touch() -> JsonObject:
    """The source of a pose a person typed, as a session or a check stores it (a captured
    one's: Capture.touch_record)."""
    source: TouchOrigin = "typed"
    return {"source": source, "read_at": None}


def touch_sources(records: Sequence[Mapping[str, object]]) -> list[TouchSource]:
    """Stored touch records as served, numbered from 0 in the order of the poses."""
    return [
        TouchSource.model_validate({**record, "index": index})
        for index, record in enumerate(records)
    ]


def settings_for_robot(
    session: Session,
    robot_id: str,
    *,
    missing: type[NoController | NoControllerSet] = NoController,
) -> ControllerSettings:
    """How to reach the robot's controller; without one `missing`: 409 /no-controller for a
    touch that needs it, 404 for a read of the controller itself (contract v1.3)."""
    return settings_of(get_controller(session, robot_id, missing=missing))


def read_still(settings: ControllerSettings, *, robot_id: str) -> Capture:
    """Read the pose twice in one session, `STILL_GAP_S` apart; 409 /robot-moving when the
    reads differ, 502 when the controller cannot be reached or refuses (no database here)."""
    try:
        with connect(settings) as conn:
            first = conn.read_pose()
            time.sleep(STILL_GAP_S)  # from the first read's answer to the second's request
            second = conn.read_pose()
    except ControllerError as exc:
        raise controller_problem(
            exc, settings, robot_id=robot_id, left="nothing was kept", refusal="connector"
        ) from None
    _still(first.flange, second.flange)
    return Capture(robot_id=robot_id, protocol=settings.protocol, reading=second, read_at=utcnow())


def _still(first: Frame, second: Frame) -> None:
    moved_mm, moved_deg = frame_deviation(
        first.position_mm, first.quaternion, second.position_mm, second.quaternion
    )
    if not within((moved_mm, moved_deg), mm=STILL_MM, deg=STILL_DEG):
        raise RobotMoving(
            f"the robot moved {moved_mm:.4f} mm and {moved_deg:.4f} deg between two reads "
            f"{STILL_GAP_S * 1000:.0f} ms apart (allowed {STILL_MM} mm and {STILL_DEG} deg): "
            "nothing was kept; let it come to rest at the touch and capture again",
            members={"moved_mm": moved_mm, "moved_deg": moved_deg},
        )


def capture(*, robot_id: str, actor: Principal) -> Capture:
    """A still reading of the robot's pose (404 /no-controller without one): how to reach
    it read in a transaction of its own, then the controller's I/O with none open."""
    with transaction_for(actor, write=False) as session:
        settings = settings_for_robot(session, robot_id, missing=NoControllerSet)
    return read_still(settings, robot_id=robot_id)


def pose_in_format(
    captured: Capture, fmt: PoseFormat, units: Units | None, *, loc: tuple[str, ...]
) -> Pose:
    """The captured flange in pose format `fmt` (joints: the controller's joint angles),
    as a typed pose in that format would be written."""
    unit_map: Mapping[str, str] | None = units.model_dump(exclude_none=True) if units else None
    if fmt == "joints":
        joints = captured.reading.joints_deg
        if joints is None:
            raise InvalidInput(
                "unsupported",
                f"the {captured.protocol} controller gave no joint angles: capture in a "
                "Cartesian format (matrix, xyz_wxyz, ...)",
                loc=loc,
            )
        to_unit = 1.0 if resolve_units(fmt, unit_map).angle == "deg" else float(np.radians(1.0))
        return [float(q) * to_unit for q in joints]
    rotation, position = captured.rotation_position()
    return pose_to_format(fmt, rotation.as_matrix(), position, units=unit_map)


def controller_pose(*, robot_id: str, fmt: PoseFormat, actor: Principal) -> ControllerPose:
    """GET /v1/robots/{robot_id}/controller/pose: a still reading, in format `fmt`."""
    captured = capture(robot_id=robot_id, actor=actor)
    reading = captured.reading
    live = reading.live_tool
    with transaction_for(actor, write=False) as session:
        matches = live_tool_matches(session, robot_id, live.frame)
    return ControllerPose(
        pose=pose_in_format(captured, fmt, None, loc=("query", "format")),
        format=fmt,
        joints_deg=None if reading.joints_deg is None else list(reading.joints_deg),
        read_at=captured.read_at,
        protocol=captured.protocol,
        still=True,
        live_tool=live_tool_out(live, matches),
        readings=dict(reading.readings),
    )
