"""`fixed_npoint`: a stationary tool's tip from N >= 4 touches by a pointer whose TCP is not
trusted: the pivot fit (app.solvers.frame.fixed_tip over app.solvers.npoint) finds both the
tip (the frame's position, base frame) and the pointer's TCP, so the pointer's active
version is not used; the answer reports the TCP found and its distance from the active one.

The tool frame's orientation: `options.align` (tool axes onto base directions, as abc_world
reads it), or three more touches with the roles origin, x, xy of the tool's own frame (the
three-point construction, touched with the TCP just found), else the base frame's axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated

import numpy as np
from pydantic import Field
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.methods.frame.base import (
    FrameContext,
    FrameMethod,
    FrameMethodRequest,
    FrameSolved,
    FrameTouch,
    RoleSet,
    parse_touches,
    touch_count,
    touch_noise_of,
)
from app.methods.frame.roles import RoleOptions
from app.methods.orientation import SignedAxis, ToolAxis
from app.schemas.common import ResourceId
from app.schemas.frame_results import Fiducial, FramePointer, FrameQuality
from app.solvers.frame import THREE_POINT, FixedTip, construct, fixed_tip, interval_scale
from app.solvers.frame.fit_points import rms
from app.solvers.frame.model import point_covariance, touch_points
from app.solvers.npoint import MIN_POSES
from app.solvers.numbering import numbered
from app.words import Algorithm, FixedNpoint, OriginXXy, PoseFormat

#: The construction of the tool frame's axes from role touches.
ORIENTATION = THREE_POINT["origin_x_xy"]
#: The fiducial the stationary tip is kept as (its point in its own frame: the origin).
TIP = "tip"


class PivotTouch(FrameTouch):
    """A touch of the fixed tool's tip (no role), or of its frame's origin, +X or XY point."""

    role: OriginXXy | None = Field(
        default=None,
        description="absent: a touch of the tip; origin, x, xy: the three touches that give "
        "the tool frame's axes",
    )


class FixedNpointOptions(RoleOptions):
    align: dict[ToolAxis, SignedAxis] | None = Field(
        default=None,
        description='tool axis -> base axis, e.g. {"z": "-z"}: the tool frame\'s axes (instead '
        "of role touches)",
        min_length=1,
        max_length=2,
    )
    algorithm: Algorithm = "robust"


class FixedNpointCalibration(FrameMethodRequest):
    method: FixedNpoint
    tool_id: ResourceId | None = Field(
        default=None,
        description="the pointer tool; its TCP is found, not used: given, the answer says how "
        "far the TCP found is from its active one",
    )
    format: PoseFormat
    touches: Annotated[
        list[PivotTouch],
        touch_count(
            MIN_POSES,
            hint="touch the fixed tool's tip from 4 or more orientations (and, for its axes, "
            "its frame's origin, x and xy points once each)",
        ),
    ]
    options: FixedNpointOptions = Field(default_factory=FixedNpointOptions)


def _split(touches: Sequence[PivotTouch]) -> tuple[list[int], list[int]]:
    """The indexes of the tip touches and of the role touches."""
    tips = [i for i, t in enumerate(touches) if t.role is None]
    return tips, [i for i, t in enumerate(touches) if t.role is not None]


def _check_touches(request: FixedNpointCalibration, tips: list[int], roles: list[int]) -> None:
    if len(tips) < MIN_POSES:
        raise InvalidInput(
            "too-few-poses",
            f"{len(tips)} touches of the tip (touches without a role), at least {MIN_POSES} "
            "needed: touch the fixed tool's tip from more orientations",
            loc=("touches",),
        )
    if roles and request.options.align is not None:
        raise InvalidInput(
            "invalid-options",
            f"{numbered('touch', roles)} give the tool frame's axes by their roles, and "
            "options.align gives them too: keep one of the two",
            loc=("options", "align"),
        )


def _estimated_noise(found: FixedTip) -> float:
    """The touch noise (mm) from the pivot fit's residuals (3n - 6 dof)."""
    used = [
        i for i in range(found.pointer.quality.n_poses) if i not in found.pointer.quality.outliers
    ]
    r = np.asarray(found.pointer.quality.residuals_mm, dtype=float)[used]
    return max(float(np.sqrt(np.sum(r**2) / max(3 * r.size - 6, 1))), 1e-9)


def run(request: FixedNpointCalibration, ctx: FrameContext) -> FrameSolved:
    """The tip and the pointer's TCP from the tip touches; the axes from align, role touches
    or the base frame."""
    tips, role_touches = _split(request.touches)
    _check_touches(request, tips, role_touches)
    rotations, positions = parse_touches(ctx, request.format, request.units, request.touches)
    configured = touch_noise_of(request.options.touch_noise_mm, ctx)
    align = request.options.align
    try:
        found = fixed_tip(
            rotations[tips],
            positions[tips],
            align=None if align is None else {str(k): str(v) for k, v in align.items()},
            algorithm=request.options.algorithm,
            touch_noise_mm=configured,
        )
    except InvalidInput as exc:  # the N-point solver speaks of poses: these are tip touches
        loc = tuple(exc.loc)
        if loc[:1] == ("poses",):
            rest = loc[1:]
            if rest and isinstance(rest[0], int):
                rest = (tips[rest[0]], *rest[1:])
            exc.loc = ("touches", *rest)
        raise
    tcp = np.asarray(found.pointer.tcp_mm, dtype=float)
    tcp_cov = np.asarray(found.pointer.quality.tcp_covariance_mm2, dtype=float)
    noise = configured if configured is not None else _estimated_noise(found)
    points = touch_points(rotations, positions, tcp)
    rotation = found.rotation
    angle_cov = np.zeros((3, 3))
    if role_touches:
        axes = construct(
            ORIENTATION,
            [str(request.touches[i].role) for i in role_touches],
            points[role_touches],
            point_covariance(rotations[role_touches], noise, tcp_cov),
            touch_noise_mm=noise,
            max_angle_sigma_deg=request.options.max_angle_sigma_deg,
            touch_index=role_touches,
        )
        rotation = axes.rotation
        angle_cov = axes.covariance[3:, 3:]
    return _solved(request, ctx, found, points, rotation, angle_cov, tips, role_touches)


def _solved(
    request: FixedNpointCalibration,
    ctx: FrameContext,
    found: FixedTip,
    points: FloatArray,
    rotation: FloatArray,
    angle_cov: FloatArray,
    tips: list[int],
    role_touches: list[int],
) -> FrameSolved:
    quality = found.pointer.quality
    n = len(request.touches)
    residuals = np.zeros(n)
    residuals[tips] = quality.residuals_mm
    outliers = [tips[i] for i in quality.outliers]
    used_tips = [i for i in tips if i not in outliers]
    cov = np.zeros((6, 6))
    cov[:3, :3] = found.tip_covariance_mm2
    cov[3:, 3:] = angle_cov
    configured = quality.sigma_source == "configured"
    dof = None if configured else 3 * len(used_tips) - 6
    tip = np.asarray(found.tip_mm, dtype=float)
    frame_quality = FrameQuality(
        n_touches=n,
        rms_mm=rms(residuals[used_tips]),
        max_mm=float(residuals[used_tips].max()),
        residuals_mm=[float(r) for r in residuals],
        position_sigma_mm=[float(s) for s in np.sqrt(np.clip(np.diag(cov)[:3], 0.0, None))],
        angle_sigma_deg=[
            float(s) for s in np.degrees(np.sqrt(np.clip(np.diag(cov)[3:], 0.0, None)))
        ],
        sigma_source=quality.sigma_source,
        interval95_scale=interval_scale(dof, 1),
        outliers=outliers,
    )
    tool = _pointer(request, ctx, found)
    worst = interval_scale(dof, 3) * float(
        np.sqrt(max(float(np.linalg.eigvalsh(found.tip_covariance_mm2)[-1]), 0.0))
    )
    summary = (
        f"{request.method} of {len(tips)} tip touches: rms {frame_quality.rms_mm:.3f} mm; the "
        f"tip is within {worst:.2f} mm (95 %); the pointer's TCP found is "
        f"[{', '.join(f'{v:.3f}' for v in found.pointer.tcp_mm)}] mm"
    )
    if tool is not None and tool.distance_from_active_mm is not None:
        summary += f", {tool.distance_from_active_mm:.3f} mm from its active one"
    fiducials = [Fiducial(name=TIP, nominal_mm=[0.0, 0.0, 0.0])] + [
        Fiducial(
            name=str(request.touches[i].role),
            nominal_mm=[float(v) for v in rotation.T @ (points[i] - tip)],
        )
        for i in role_touches
    ]
    return FrameSolved(
        position_mm=tip,
        quaternion=np.asarray(
            Rotation.from_matrix(rotation).as_quat(canonical=True, scalar_first=True)
        ),
        quality=frame_quality,
        points_mm=points,
        tool=tool,
        summary=summary,
        fiducials=fiducials,
        warnings=list(found.warnings),
        covariance=cov,
    )


def _pointer(
    request: FixedNpointCalibration, ctx: FrameContext, found: FixedTip
) -> FramePointer | None:
    """The pointer as the answer reports it: the TCP found, and its distance from the active
    (or named) version when the pointer has one."""
    if request.tool_id is None:
        return None
    known = ctx.pointer(request.tool_id, request.tcp_version)
    tcp = np.asarray(found.pointer.tcp_mm, dtype=float)
    return FramePointer(
        tool_id=request.tool_id,
        version=None,
        tcp_sigma_mm=None,
        tcp_found_mm=[float(v) for v in tcp],
        tcp_found_sigma_mm=[float(s) for s in found.pointer.quality.tcp_sigma_mm],
        distance_from_active_mm=None
        if known is None
        else float(np.linalg.norm(tcp - known.pointer.tcp_mm)),
    )


FIXED_NPOINT_FRAME = FrameMethod(
    request=FixedNpointCalibration,
    run=run,
    description="a stationary tool: N >= 4 touches of its tip from different orientations by "
    "a pointer whose TCP is found too -> the tip (and the pointer's TCP); axes from "
    "options.align, three role touches (origin, x, xy), else the base frame's",
    example_body={
        "tool_id": "pointer",
        "format": "kuka_abc",
        "touches": [
            {"pose": [753.897, -81.965, 320.965, -108.243, -25.048, -167.066]},
            {"pose": [726.441, -182.084, 364.264, -43.964, -1.541, 178.498]},
            {"pose": [769.644, -132.861, 362.962, -173.468, 24.67, -168.342]},
            {"pose": [765.433, -235.479, 370.082, 101.353, 4.856, 153.693]},
            {"pose": [794.554, -232.496, 372.164, 121.53, 4.518, 160.09]},
            {"pose": [767.49, -192.016, 376.066, -41.68, 12.681, 169.542]},
        ],
        "options": {"align": {"z": "-z"}},
    },
    kinds=("fixed_tool",),
    roles=(RoleSet(convention=None, words=dict(ORIENTATION.words)),),
)
