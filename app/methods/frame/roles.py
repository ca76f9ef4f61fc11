"""What the role methods share (three_point, four_point, and fixed_npoint's orientation
touches): a touch with a role, the angle limit, and a construction over the touches."""

from __future__ import annotations

from collections.abc import Sequence

from pydantic import Field

from app.arrays import FloatArray
from app.methods.frame.base import (
    FrameContext,
    FrameSolved,
    FrameTouch,
    NoiseOption,
    PointerTcp,
    TouchedFrameRequest,
    configured_noise,
    parse_touches,
    solved_from_estimate,
    touched_with,
    touches_covariance,
)
from app.schemas.common import PositiveFloat
from app.solvers.frame import MAX_ANGLE_SIGMA_DEG, Construction, FrameEstimate, construct
from app.solvers.frame.model import touch_points
from app.words import FrameRole


class RoleTouch(FrameTouch):
    """A touch of the point a role names."""

    role: FrameRole = Field(
        description="which point this touch is (GET /v1/methods lists each method's roles)"
    )


class RoleOptions(NoiseOption):
    max_angle_sigma_deg: PositiveFloat = Field(
        default=MAX_ANGLE_SIGMA_DEG,
        description="refuse touches that leave an axis uncertain by more than this (1-sigma, "
        "deg), saying how far the touch that sets it must be",
    )


class RoleRequest(TouchedFrameRequest):
    """A calibration from role touches (each method narrows `touches` and `options`)."""

    touches: list[RoleTouch]
    options: RoleOptions


def role_hint(construction: Construction) -> str:
    """The touches a construction takes, in words, in the order they are taught."""
    return "; ".join(f"{role}: {construction.words[role]}" for role in construction.roles)


def construct_frame(
    construction: Construction,
    roles: Sequence[str],
    rotations: FloatArray,
    positions_mm: FloatArray,
    pointer: PointerTcp,
    *,
    touch_noise_mm: float,
    max_angle_sigma_deg: float,
) -> FrameEstimate:
    """The construction's frame from role touches with the pointer, the touch noise and the
    pointer's TCP covariance propagated."""
    points = touch_points(rotations, positions_mm, pointer.pointer.tcp_mm)
    covariance = touches_covariance(rotations, touch_noise_mm, pointer)
    return construct(
        construction,
        roles,
        points,
        covariance,
        touch_noise_mm=touch_noise_mm,
        max_angle_sigma_deg=max_angle_sigma_deg,
    )


def solve_roles(
    request: RoleRequest, ctx: FrameContext, construction: Construction, what: str
) -> FrameSolved:
    """A role method's run: the pointer, the configured noise, the touches read, the frame
    constructed; `what` says which construction in the summary."""
    pointer = touched_with(request, ctx)
    noise = configured_noise(request.options.touch_noise_mm, ctx, request.method)
    rotations, positions = parse_touches(ctx, request.format, request.units, request.touches)
    roles = [t.role for t in request.touches]
    estimate = construct_frame(
        construction,
        roles,
        rotations,
        positions,
        pointer,
        touch_noise_mm=noise,
        max_angle_sigma_deg=request.options.max_angle_sigma_deg,
    )
    return solved_from_estimate(
        estimate, names=roles, pointer=pointer, what=f"{what} from {len(roles)} touches"
    )
