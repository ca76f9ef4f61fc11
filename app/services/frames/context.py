"""The frame methods' context backed by the database (app.methods.frame.base.FrameContext): the
frame's kind and tolerance, the robot's pose reading, and the pointer tool's TCP: its active
version or the one named, with the covariance its calibration reported."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.methods.frame.base import PointerTcp
from app.schemas.common import Pose, Units
from app.schemas.frame_tolerance import FrameTolerance
from app.services.frames.frames import frame_tolerance
from app.services.touches.tool_frames import frame_of, parse_poses_with
from app.services.visible import visible_tool
from app.solvers.frame import Pointer
from app.storage.models import Frame, Robot, TcpVersion
from app.words import FrameKind, PoseFormat


class FrameDbContext:
    """What a frame method may look up, for one frame of one robot."""

    def __init__(self, session: Session, frame: Frame, robot: Robot) -> None:
        self.session, self.frame, self.robot = session, frame, robot

    @property
    def kind(self) -> FrameKind:
        return self.frame.kind

    @property
    def tolerance(self) -> FrameTolerance:
        return frame_tolerance(self.frame.tolerance)

    def parse_poses(
        self,
        fmt: PoseFormat,
        poses: Sequence[Pose],
        units: Units | None,
        *,
        loc: Sequence[str | int],
    ) -> tuple[FloatArray, FloatArray]:
        return parse_poses_with(self.robot.kinematics, fmt, poses, units, loc=loc)

    def pointer(self, tool_id: str, version: int | None) -> PointerTcp | None:
        """The pointer tool of the frame's robot and its TCP (its active version, or
        `version`); None when it has no active version and none is named."""
        tool = visible_tool(self.session, tool_id)
        if tool is None or tool.archived_at is not None or tool.robot_id != self.robot.id:
            raise InvalidInput(
                "unknown-reference",
                f"robot {self.robot.name} has no tool {tool_id} in service to touch with; name "
                f"one of its live tools (GET /v1/robots/{self.robot.id}/tools)",
                loc=("tool_id",),
            )
        wanted = tool.active_version if version is None else version
        if wanted is None:
            return None
        row = self.session.scalars(
            select(TcpVersion).where(TcpVersion.tool_id == tool.id, TcpVersion.version == wanted)
        ).one_or_none()
        if row is None:
            raise InvalidInput(
                "unknown-reference",
                f"tool {tool.name} has no TCP version {wanted}; its versions are listed at "
                f"GET /v1/tools/{tool.id}/versions",
                loc=("tcp_version",),
            )
        tcp = frame_of(self.session, row)
        covariance = np.zeros((3, 3)) if tcp.covariance_mm2 is None else tcp.covariance_mm2
        return PointerTcp(tool.id, row.version, Pointer(tcp.position_mm, covariance))
