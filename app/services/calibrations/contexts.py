"""Method contexts: what a calibration method may look up, from the database or from nothing.

Locations in the errors they raise are body-relative, like every error raised inside a
method; the calibration service roots them.

DbContext serves stored calibrations (one tool of one robot); StatelessContext serves
POST /v1/solve and refuses every lookup that would need storage, naming the field to fill.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from sqlalchemy.orm import Session

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.helpers.tolerance import effective_tolerance
from app.methods.base import ActiveFrame, StoredPoint
from app.schemas.common import Pose, Units
from app.schemas.tools import Tolerance
from app.services.touches.tool_frames import active_frame, parse_poses_with
from app.storage.models import LaserDevice, ReferencePoint, Robot, Tool
from app.words import PoseFormat

#: Poses read: rotations (N, 3, 3) and flange positions (N, 3) mm.
PosesRead = tuple[FloatArray, FloatArray]


class _Readings:
    """Poses as read under each format and units asked for, each read once: a calibration's
    method reads the submission's poses, and the mix-up check
    (app.services.calibrations.grading.solve) reads them again, and under other readings when
    the fit is poor. Callers get copies."""

    def __init__(self) -> None:
        self._done: list[tuple[Sequence[Pose], str, Units | None, PosesRead]] = []

    def read(
        self,
        kinematics: Mapping[str, object] | None,
        fmt: PoseFormat,
        poses: Sequence[Pose],
        units: Units | None,
        loc: Sequence[str | int],
    ) -> PosesRead:
        for seen, seen_fmt, seen_units, (rotations, positions) in self._done:
            if seen is poses and seen_fmt == fmt and seen_units == units:
                return rotations.copy(), positions.copy()
        rotations, positions = parse_poses_with(kinematics, fmt, poses, units, loc=loc)
        self._done.append((poses, fmt, units, (rotations, positions)))  # keeps `poses` alive
        return rotations.copy(), positions.copy()


class DbContext:
    """Method context backed by the database, for one tool of one robot."""

    def __init__(self, session: Session, tool: Tool, robot: Robot) -> None:
        self.session, self.tool, self.robot = session, tool, robot
        self._readings = _Readings()

    @property
    def tolerance(self) -> Tolerance:
        return effective_tolerance(self.tool.tolerance)

    def active_frame(self) -> ActiveFrame | None:
        return active_frame(self.session, self.tool)

    def parse_poses(
        self,
        fmt: PoseFormat,
        poses: Sequence[Pose],
        units: Units | None,
        *,
        loc: Sequence[str | int],
    ) -> PosesRead:
        return self._readings.read(self.robot.kinematics, fmt, poses, units, loc)

    def reference_point(self, reference_point_id: str) -> StoredPoint:
        row = self.session.get(ReferencePoint, reference_point_id)
        if row is None or row.robot_id != self.robot.id:
            raise InvalidInput(
                "unknown-reference",
                f"robot {self.robot.id} has no reference point {reference_point_id}",
                loc=("options", "reference_point_id"),
            )
        cov = np.asarray(row.covariance_mm2, dtype=float) if row.covariance_mm2 else None
        return StoredPoint(np.asarray(row.position_mm, dtype=float), cov)

    def tool_frame(self, tool_id: str) -> ActiveFrame:
        other = self.session.get(Tool, tool_id)
        if other is None or other.archived_at is not None or other.robot_id != self.robot.id:
            raise InvalidInput(
                "unknown-reference",
                f"robot {self.robot.id} has no live tool {tool_id}",
                loc=("options", "reference_tool_id"),
            )
        frame = active_frame(self.session, other)
        if frame is None:
            raise InvalidInput(
                "unknown-reference",
                f"reference tool {tool_id} has no active TCP to trust",
                loc=("options", "reference_tool_id"),
            )
        return frame

    def laser_device(self, device_id: str) -> tuple[float, float, float]:
        row = self.session.get(LaserDevice, device_id)
        if row is None or row.robot_id != self.robot.id:
            raise InvalidInput(
                "unknown-reference",
                f"robot {self.robot.id} has no laser device {device_id}",
                loc=("laser", "device_id"),
            )
        return row.beam_a_y_mm, row.beam_b_x_mm, row.plane_z_mm


class StatelessContext:
    """Method context for POST /v1/solve: nothing stored is read except an optional robot."""

    def __init__(
        self, kinematics: Mapping[str, object] | None, tolerance: Tolerance | None
    ) -> None:
        self._kinematics = kinematics
        self._tolerance = effective_tolerance(tolerance)
        self._readings = _Readings()

    @property
    def tolerance(self) -> Tolerance:
        return self._tolerance

    def active_frame(self) -> ActiveFrame | None:
        return None

    def parse_poses(
        self,
        fmt: PoseFormat,
        poses: Sequence[Pose],
        units: Units | None,
        *,
        loc: Sequence[str | int],
    ) -> PosesRead:
        return self._readings.read(self._kinematics, fmt, poses, units, loc)

    def _stored(self, what: str, field: tuple[str, ...], instead: str) -> InvalidInput:
        return InvalidInput(
            "needs-storage",
            f"/v1/solve stores nothing and cannot look up {what}; {instead}",
            loc=field,
        )

    def reference_point(self, reference_point_id: str) -> StoredPoint:
        raise self._stored(
            "a reference point",
            ("options", "reference_point_id"),
            "give options.reference_point_mm",
        )

    def tool_frame(self, tool_id: str) -> ActiveFrame:
        raise self._stored(
            "another tool's TCP",
            ("options", "reference_tool_id"),
            "give options.reference_point_mm",
        )

    def laser_device(self, device_id: str) -> tuple[float, float, float]:
        raise self._stored(
            "a laser device", ("laser", "device_id"), "give beam_a_y_mm, beam_b_x_mm and plane_z_mm"
        )


class SnapshotContext(StatelessContext):
    """What a stored calibration's solve reads, copied out of the database beforehand (the
    tool's tolerance and active frame, the robot's model), so that it can solve in a solver
    process with no session. Lookups of other stored things are refused as `needs-storage`;
    the caller then solves with a DbContext instead."""

    def __init__(
        self,
        kinematics: Mapping[str, object] | None,
        tolerance: Tolerance | None,
        active: ActiveFrame | None,
    ) -> None:
        super().__init__(kinematics, tolerance)
        self._active = active

    def active_frame(self) -> ActiveFrame | None:
        return self._active
