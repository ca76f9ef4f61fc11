"""The next touch of a guided frame session, in words (API.md v1.4 "Sessions:" `next_role`).

A role method's touches are taught in its construction's order; the touch that sets a
direction (the x touch from the origin, the xy touch from the X axis) is told how far it
must be for the method's angle tolerance (`max_angle_sigma_deg`) with the frame's touch
noise, the distance the construction's refusal would ask for after the touch
(app.solvers.frame.construction.distance_for_angle_mm). fit_points asks for touches of
drawn points with their nominal_mm, fixed_npoint for the tip from varied orientations and
then, optionally, the origin, x and xy of the tool's own frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from app.methods.frame.fit_points import FIT_POINTS_FRAME
from app.methods.frame.fixed_npoint import FIXED_NPOINT_FRAME, ORIENTATION
from app.methods.frame.four_point import FOUR_POINT_FRAME
from app.methods.frame.three_point import THREE_POINT_FRAME, ThreePointOptions
from app.solvers.frame import FOUR_POINT, MAX_ANGLE_SIGMA_DEG, THREE_POINT, Construction
from app.solvers.frame.construction import distance_for_angle_mm
from app.solvers.frame.fit_points import MIN_POINTS, TOUCHES_PER_OUTLIER
from app.solvers.npoint import MIN_POSES
from app.words import FrameMethodName, FrameTouchTakes, ThreePointConvention


@dataclass(frozen=True)
class NextRole:
    """What to touch next: the role to send (None for a touch with none), in words."""

    role: str | None
    takes: FrameTouchTakes
    words: str
    #: the touches so far can be finished (more may still help)
    enough: bool


def construction_of(
    method: FrameMethodName, convention: ThreePointConvention | None
) -> Construction | None:
    """The construction whose roles a method's touches take (fixed_npoint: its tool frame's
    optional axes), None for a method whose touches take no role."""
    if method == THREE_POINT_FRAME.name:
        return THREE_POINT[convention or ThreePointOptions().convention]
    return {FOUR_POINT_FRAME.name: FOUR_POINT, FIXED_NPOINT_FRAME.name: ORIENTATION}.get(method)


def next_role(
    method: FrameMethodName,
    roles: Sequence[str | None],
    *,
    convention: ThreePointConvention | None = None,
    touch_noise_mm: float | None = None,
    max_angle_sigma_deg: float = MAX_ANGLE_SIGMA_DEG,
) -> NextRole | None:
    """The next touch after touches with `roles` (None: a touch with no role), or None when
    the method takes no more (its roles all touched; manual takes none)."""
    n = len(roles)
    if method == FIT_POINTS_FRAME.name:
        return NextRole(
            None,
            "nominal_mm",
            f"touch {n + 1}: a point whose coordinates the fixture's drawing gives, sent with "
            f"them as nominal_mm (at least {MIN_POINTS}, not on one line; from "
            f"{TOUCHES_PER_OUTLIER} on a bad touch is found and named)",
            enough=n >= MIN_POINTS,
        )
    construction = construction_of(method, convention)
    if construction is None:
        return None
    done = {r for r in roles if r is not None}
    if method == FIXED_NPOINT_FRAME.name:
        tips = n - len(done)
        if tips < MIN_POSES:
            return NextRole(
                None,
                "tip",
                f"touch the fixed tool's tip with the pointer, tilted another way than before "
                f"(tip touch {tips + 1} of at least {MIN_POSES})",
                enough=False,
            )
    todo = [r for r in construction.roles if r not in done]
    if not todo:
        return None
    role = todo[0]
    how_far = _how_far(construction, role, touch_noise_mm, max_angle_sigma_deg)
    words = f"touch {construction.words[role]}{how_far}"
    optional = method == FIXED_NPOINT_FRAME.name and not done
    if optional:
        words += "; or finish now, and the tool frame takes the base frame's axes"
    return NextRole(role, "role", words, enough=optional)


def _how_far(
    construction: Construction, role: str, touch_noise_mm: float | None, limit_deg: float
) -> str:
    """How far the touch of `role` must be from what it sets a direction from, in words."""
    if role == construction.x_role:
        frm = f"the {construction.axis_from} touch"
    elif role == construction.plane_role:
        frm = "the X axis"
    else:
        return ""
    if touch_noise_mm is None:
        return (
            f", far from {frm} (set the touch noise, options.touch_noise_mm or the frame's "
            "tolerance, to be told how far)"
        )
    need = math.ceil(distance_for_angle_mm(touch_noise_mm, limit_deg))
    return f", at least {need} mm from {frm}"
