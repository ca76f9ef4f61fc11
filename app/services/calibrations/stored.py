"""Stored calibrations as served: one (with the submission and its touches in space), and
a tool's list."""

from __future__ import annotations

from datetime import datetime

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import InvalidInput, NotFound
from app.helpers.pagination import paginate
from app.methods.requests import CALIBRATION_REQUESTS
from app.schemas.results import (
    Calibration,
    CalibrationDetail,
    CalibrationResult,
    TouchGeometry,
)
from app.services.controllers.capture import touch_sources
from app.services.robots.robots import get_robot
from app.services.tools.tools import get_tool
from app.services.touches.tool_frames import parse_poses_with
from app.services.visible import visible_tool
from app.solvers.quality import ellipsoid_semi_axes
from app.storage.models import Calibration as CalibrationRow
from app.storage.models import Tool


def calibration_out(row: CalibrationRow, tool: Tool) -> Calibration:
    """A stored calibration as served."""
    return served(
        CalibrationResult.model_validate(row.result),
        id=row.id,
        tool_id=row.tool_id,
        version=row.version,
        active_version=tool.active_version,
        created_at=row.created_at,
        created_by=row.created_by,
    )


def served(
    result: CalibrationResult,
    *,
    id: str,
    tool_id: str,
    version: int | None,
    active_version: int | None,
    created_at: datetime,
    created_by: str,
) -> Calibration:
    """A calibration's result as served, with its row's fields (stored now, or read)."""
    # The result was validated when it was made (or read): the served document reuses its
    # fields as they are instead of validating them all again.
    return Calibration.model_construct(
        **dict(result),
        id=id,
        tool_id=tool_id,
        version=version,
        active=version is not None and active_version == version,
        created_at=created_at,
        created_by=created_by,
    )


def list_calibrations(
    session: Session, *, tool_id: str, limit: int, cursor: str | None
) -> tuple[list[Calibration], str | None]:
    """A tool's calibrations, oldest first."""
    tool = get_tool(session, tool_id)
    rows, next_cursor = paginate(
        session,
        select(CalibrationRow).where(CalibrationRow.tool_id == tool_id),
        created_col=CalibrationRow.created_at,
        id_col=CalibrationRow.id,
        limit=limit,
        cursor=cursor,
    )
    return [calibration_out(r, tool) for r in rows], next_cursor


def get_calibration(session: Session, *, calibration_id: str) -> CalibrationDetail:
    """One calibration with the submission as received."""
    row = session.get(CalibrationRow, calibration_id)
    tool = None if row is None else visible_tool(session, row.tool_id)
    if row is None or tool is None:  # a tool of another cell's robot: as if absent
        raise NotFound(f"no calibration with id {calibration_id}")
    out = calibration_out(row, tool)
    return CalibrationDetail(
        **out.model_dump(),
        request=row.request,
        geometry=_geometry(session, row, tool, out),
        touches=None if row.touches is None else touch_sources(row.touches),
    )


def _geometry(
    session: Session, row: CalibrationRow, tool: Tool, out: Calibration
) -> TouchGeometry | None:
    """The touches of a stored submission in space, read again from the request."""
    request = CALIBRATION_REQUESTS.validate_python(row.request)
    if not request.poses or request.format is None:
        return None
    robot = get_robot(session, tool.robot_id)
    try:
        rotations, flanges = parse_poses_with(
            robot.kinematics, request.format, request.poses, request.units, loc=()
        )
    except InvalidInput:  # the robot's kinematics changed since: no picture, the rest stands
        return None
    tips = flanges + rotations @ np.asarray(out.tcp.position_mm)
    geometry = TouchGeometry(flange_positions_mm=flanges.tolist(), tip_positions_mm=tips.tolist())
    quality = out.quality
    if quality.tcp_covariance_mm2 is not None and quality.ellipsoid95_scale is not None:
        semi, axes = ellipsoid_semi_axes(quality.tcp_covariance_mm2, quality.ellipsoid95_scale)
        geometry.ellipsoid95_semi_axes_mm, geometry.ellipsoid95_axes = semi.tolist(), axes.tolist()
    return geometry
