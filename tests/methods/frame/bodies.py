"""Request bodies of simulated frame touches (testbed.sim.cell_frames), in xyz_wxyz."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.jsontypes import JsonObject
from app.methods.frame import FRAME_CALIBRATION_REQUESTS, FRAME_METHODS_BY_NAME
from app.methods.frame.base import FrameSolved
from app.solvers.frame import Pointer
from testbed.sim.cell_frames import FrameTouches, touch_frame
from tests.methods.frame.given import GivenPointer


def poses(rotations: FloatArray, positions_mm: FloatArray) -> list[list[float]]:
    """Flange poses as xyz_wxyz rows."""
    q = Rotation.from_matrix(rotations).as_quat(scalar_first=True)
    return [[*map(float, p), *map(float, w)] for p, w in zip(positions_mm, q, strict=True)]


def role_body(
    method: str, touches: FrameTouches, roles: Sequence[str], **extra: object
) -> JsonObject:
    """A role method's body: touch i has roles[i]."""
    rows = poses(touches.rotations, touches.positions_mm)
    return {
        "method": method,
        "tool_id": "pointer",
        "format": "xyz_wxyz",
        "touches": [{"role": r, "pose": p} for r, p in zip(roles, rows, strict=True)],
        **extra,
    }


def nominal_body(method: str, touches: FrameTouches, **extra: object) -> JsonObject:
    """A fit_points body: touch i carries the nominal point it touched."""
    rows = poses(touches.rotations, touches.positions_mm)
    return {
        "method": method,
        "tool_id": "pointer",
        "format": "xyz_wxyz",
        "touches": [
            {"nominal_mm": [float(v) for v in n], "pose": p}
            for n, p in zip(touches.nominal_mm, rows, strict=True)
        ],
        **extra,
    }


def solve(body: JsonObject, ctx: GivenPointer) -> FrameSolved:
    """Validate a body as the API does and run its method."""
    request = FRAME_CALIBRATION_REQUESTS.validate_python(body)
    return FRAME_METHODS_BY_NAME[request.method].solve(request, ctx)


def context(touches: FrameTouches, tcp_sigma_mm: float = 0.0, **kw: object) -> GivenPointer:
    """The context of a pointer with the TCP the touches were read with."""
    pointer = Pointer.of(touches.tcp_mm, [tcp_sigma_mm] * 3)
    return GivenPointer.of(pointer, **kw)  # type: ignore[arg-type]


def angle_deg(q_wxyz: FloatArray, R: FloatArray) -> float:
    """The angle between a quaternion's rotation and a matrix, deg."""
    found = Rotation.from_quat(np.asarray(q_wxyz), scalar_first=True)
    return float(np.degrees((found.inv() * Rotation.from_matrix(R)).magnitude()))


def refused(body: JsonObject, ctx: GivenPointer) -> InvalidInput:
    """The refusal a body gets."""
    with pytest.raises(InvalidInput) as caught:
        solve(body, ctx)
    return caught.value


def coverage(
    seed: int,
    nominal_mm: FloatArray,
    body_of: Callable[[FrameTouches], JsonObject],
    *,
    sets: int = 400,
) -> float:
    """The share of origin coordinates and small angles (frame axes) within their reported
    95 % intervals, over `sets` seeded sets of 0.05 mm touches by a pointer whose TCP is off
    by 0.02 mm (1-sigma per axis, the same error at every touch of a set)."""
    rng = np.random.default_rng(seed)
    inside = total = 0
    for _ in range(sets):
        touches = touch_frame(rng, nominal_mm, touch_noise_mm=0.05, tcp_sigma_mm=0.02)
        solved = solve(body_of(touches), context(touches, 0.02))
        k = solved.quality.interval95_scale
        assert k is not None
        assert solved.quality.position_sigma_mm is not None
        assert solved.quality.angle_sigma_deg is not None
        found = Rotation.from_quat(solved.quaternion, scalar_first=True)
        angle = np.degrees((Rotation.from_matrix(touches.frame_rotation).inv() * found).as_rotvec())
        error = np.abs(np.concatenate([solved.position_mm - touches.frame_origin_mm, angle]))
        sigma = np.array(solved.quality.position_sigma_mm + solved.quality.angle_sigma_deg)
        inside += int(np.sum(error <= k * sigma))
        total += 6
    return inside / total
