"""Which TCP each robot moves by right now (contract v1.3, LiveTool): the versions of the
robot's tools that equal the tool frame its controller reports, and what the reconcile
rounds last found, one row a robot.

A version equals the live frame within SYNC_TOLERANCE_MM and SYNC_TOLERANCE_DEG, the
tolerances a reconcile finds a tool in sync by: a frame the controller holds is its
version when a reconcile would call them the same.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.controllers.base import Frame
from app.helpers.frames import SYNC_TOLERANCE_DEG, SYNC_TOLERANCE_MM, frame_deviation, within
from app.models import TcpVersion, Tool
from app.schemas.controllers import LiveToolMatch


def live_tool_matches(session: Session, robot_id: str, frame: Frame | None) -> list[LiveToolMatch]:
    """Every version of the robot's live tools whose frame equals `frame` (within 0.01 mm
    and 0.01 deg), oldest tool first and by version; none when the frame is not known. The
    caller limits the session to the robots its key may see (app.auth.act_for)."""
    if frame is None:
        return []
    rows = session.execute(
        select(
            TcpVersion.tool_id,
            TcpVersion.version,
            TcpVersion.position_mm,
            TcpVersion.quaternion,
            Tool.active_version,
        )
        .join(Tool, Tool.id == TcpVersion.tool_id)
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
        .order_by(Tool.created_at, Tool.id, TcpVersion.version)
    )
    return [
        LiveToolMatch(tool_id=tool_id, version=version, active=version == active)
        for tool_id, version, position_mm, quaternion, active in rows
        if within(
            frame_deviation(frame.position_mm, frame.quaternion, position_mm, quaternion),
            mm=SYNC_TOLERANCE_MM,
            deg=SYNC_TOLERANCE_DEG,
        )
    ]
