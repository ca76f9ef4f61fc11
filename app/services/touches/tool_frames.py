"""Reading poses and a tool's trusted frame: shared by calibrations, references and checks."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from sqlalchemy.orm import Session

from app.arrays import FloatArray
from app.kinematics.dh import kinematics_from_spec
from app.kinematics.poses import poses_from_format
from app.methods.base import ActiveFrame
from app.schemas.common import Pose, Units
from app.services.tools.versions import active_version_row
from app.storage.models import Calibration, TcpVersion, Tool
from app.vendors.registry import PRESETS
from app.words import PoseFormat


def parse_poses_with(
    kinematics: Mapping[str, object] | None,
    fmt: PoseFormat,
    poses: Sequence[Pose],
    units: Units | None,
    *,
    loc: Sequence[str | int],
) -> tuple[FloatArray, FloatArray]:
    """Poses in any format -> (R, f), with the robot's kinematics for `joints`."""
    chain = kinematics_from_spec(kinematics, presets=PRESETS) if kinematics else None
    unit_map = units.model_dump(exclude_none=True) if units else None
    return poses_from_format(fmt, poses, units=unit_map, kinematics=chain, loc=loc)


def active_frame(session: Session, tool: Tool) -> ActiveFrame | None:
    """A tool's active TCP with the covariance its calibration reported (None: no version)."""
    if tool.active_version is None:
        return None
    return frame_of(session, active_version_row(session, tool))


def frame_of(session: Session, row: TcpVersion) -> ActiveFrame:
    """A version's TCP with the covariance its calibration reported."""
    calibration = session.get(Calibration, row.calibration_id) if row.calibration_id else None
    return frame_from(
        row.position_mm, row.quaternion, row.version, calibration.result if calibration else None
    )


def frame_from(
    position_mm: Sequence[float],
    quaternion: Sequence[float],
    version: int,
    calibration_result: Mapping[str, object] | None,
) -> ActiveFrame:
    """A stored version's frame, with the covariance from its calibration's result if any."""
    quality = calibration_result.get("quality") if calibration_result else None
    cov = quality.get("tcp_covariance_mm2") if isinstance(quality, Mapping) else None
    return ActiveFrame(
        position_mm=np.asarray(position_mm, dtype=float),
        quaternion=np.asarray(quaternion, dtype=float),
        covariance_mm2=np.asarray(cov, dtype=float) if cov else None,
        version=version,
    )
