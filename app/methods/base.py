"""What every calibration method shares: its context (lookups it may need) and its outcome.

A method is one function `run(request, ctx) -> SolvedTcp` over one solver module and one
request schema. It reads what it needs from the context (the tool's active TCP, a stored
reference point, the robot's kinematics), so the same function serves stored calibrations
(a database-backed context) and POST /v1/solve (a stateless one).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from app.schemas.common import Units
from app.solvers.orientation import angle_between_deg


@dataclass(frozen=True)
class ActiveFrame:
    """A tool's trusted TCP: position (mm, flange), orientation [w, x, y, z], 3x3 covariance."""

    position_mm: NDArray[np.float64]
    quaternion: NDArray[np.float64]
    covariance_mm2: NDArray[np.float64] | None
    version: int | None = None


@dataclass(frozen=True)
class StoredPoint:
    """A reference point in the robot base frame (mm) and its covariance when known."""

    position_mm: NDArray[np.float64]
    covariance_mm2: NDArray[np.float64] | None


@dataclass
class SolvedTcp:
    """What a method computed, before grading, versioning and storage."""

    position_mm: NDArray[np.float64]
    quaternion: NDArray[np.float64] | None  # None: position-only method, keep orientation
    algorithm: str | None
    quality: dict[str, Any]
    warnings: list[str] = field(default_factory=list)
    reference_point_mm: list[float] | None = None
    reference_covariance_mm2: list[list[float]] | None = None
    graded: bool = True  # False for numbers entered by hand: no residuals to grade
    extra: dict[str, Any] = field(default_factory=dict)


class MethodContext(Protocol):
    """Lookups a method may need; the stateless context refuses those that need storage."""

    @property
    def tolerance(self) -> dict[str, Any]: ...

    def active_frame(self) -> ActiveFrame | None: ...

    def parse_poses(
        self, fmt: str, poses: Sequence[Any], units: Units | None, *, loc: Sequence[str | int]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...

    def reference_point(self, reference_point_id: str) -> StoredPoint: ...

    def tool_frame(self, tool_id: str) -> ActiveFrame: ...

    def laser_device(self, device_id: str) -> tuple[float, float, float]: ...


def orientation_change_deg(ctx: MethodContext, quaternion: Sequence[float]) -> float | None:
    """Angle (deg) from the tool's active orientation to a new one; None without one."""
    frame = ctx.active_frame()
    return None if frame is None else angle_between_deg(frame.quaternion, quaternion)


def empty_quality(n_poses: int) -> dict[str, Any]:
    """Quality of a result that has no redundancy to measure (numbers entered by hand)."""
    return {
        "n_poses": n_poses,
        "rms_mm": None,
        "max_mm": None,
        "residuals_mm": [],
        "tcp_sigma_mm": None,
        "tcp_covariance_mm2": None,
        "sigma_source": None,
        "orientation_spread_deg": None,
        "condition_number": None,
        "outliers": [],
    }
