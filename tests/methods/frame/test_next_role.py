"""The next touch of a guided frame session in words: each method's roles in their order, and
the distance told before the x and xy touches is the one the construction's refusal asks for
after them (so a person who follows the words is never refused for spread)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from app.errors import InvalidInput
from app.methods.frame.next_role import next_role
from app.solvers.frame import THREE_POINT, construct, point_covariance
from app.solvers.frame.construction import distance_for_angle_mm

NOISE_MM = 0.05
TCP_SIGMA_MM = 0.02


def _told_mm(words: str) -> int:
    found = re.search(r"at least (\d+) mm", words)
    assert found is not None, words
    return int(found.group(1))


def test_three_point_asks_origin_then_x_then_xy_with_the_distance() -> None:
    first = next_role("three_point", [], touch_noise_mm=NOISE_MM)
    assert first is not None
    assert (first.role, first.takes, first.enough) == ("origin", "role", False)
    assert first.words == "touch the frame's origin"
    x = next_role("three_point", ["origin"], touch_noise_mm=NOISE_MM)
    assert x is not None
    assert x.role == "x"
    assert x.words == "touch a point on the frame's +X axis, at least 82 mm from the origin touch"
    xy = next_role("three_point", ["origin", "x"], touch_noise_mm=NOISE_MM)
    assert xy is not None
    assert xy.role == "xy"
    assert xy.words.endswith("on the +Y side of the X axis, at least 82 mm from the X axis")
    assert next_role("three_point", ["origin", "x", "xy"], touch_noise_mm=NOISE_MM) is None


def test_the_distance_follows_the_angle_tolerance_and_the_noise() -> None:
    x = next_role("three_point", ["origin"], touch_noise_mm=0.1, max_angle_sigma_deg=0.04)
    assert x is not None
    assert _told_mm(x.words) == math.ceil(math.sqrt(2) * 0.1 / math.radians(0.04)) == 203
    unknown = next_role("three_point", ["origin"])
    assert unknown is not None
    assert "far from the origin touch (set the touch noise" in unknown.words


@pytest.mark.parametrize(("role", "at"), [("x", 0.97), ("x", 1.03), ("xy", 0.97), ("xy", 1.03)])
def test_the_distance_told_is_the_one_the_refusal_asks_for(role: str, at: float) -> None:
    """Touched in one orientation with a pointer whose TCP has 0.02 mm sigma, a point 3 %
    short of the distance told is refused asking for that distance, 3 % past it is taken."""
    need = distance_for_angle_mm(NOISE_MM, 0.05)
    far = 10 * need
    x_at, xy_at = (at * need, far) if role == "x" else (far, at * need)
    points = np.array([[0.0, 0.0, 0.0], [x_at, 0.0, 0.0], [0.0, xy_at, 0.0]])
    rotations = np.repeat(np.eye(3)[None], 3, axis=0)
    covariance = point_covariance(rotations, NOISE_MM, TCP_SIGMA_MM**2 * np.eye(3))
    told = next_role(
        "three_point", ["origin", "x"][: 1 if role == "x" else 2], touch_noise_mm=NOISE_MM
    )
    assert told is not None
    assert told.role == role

    def solve() -> object:
        return construct(
            THREE_POINT["origin_x_xy"],
            ["origin", "x", "xy"],
            points,
            covariance,
            touch_noise_mm=NOISE_MM,
        )

    if at < 1:
        with pytest.raises(InvalidInput) as refused:
            solve()
        assert refused.value.kind == "insufficient-spread"
        assert f"at least {_told_mm(told.words)} mm" in refused.value.detail
    else:
        solve()


def test_abb_user_and_four_point_take_their_own_roles() -> None:
    abb = next_role("three_point", ["x1"], convention="abb_user", touch_noise_mm=NOISE_MM)
    assert abb is not None
    assert abb.role == "x2"
    assert abb.words.endswith("at least 82 mm from the x1 touch")
    four = [next_role("four_point", ["x_start", "x", "xy"][:k]) for k in range(4)]
    assert [f.role for f in four if f is not None] == ["x_start", "x", "xy", "origin"]


def test_fit_points_asks_for_nominal_points_and_is_enough_from_three() -> None:
    told = [next_role("fit_points", [None] * k) for k in range(5)]
    assert all(t is not None and t.takes == "nominal_mm" and t.role is None for t in told)
    assert [t.enough for t in told if t is not None] == [False, False, False, True, True]
    assert told[0] is not None
    assert told[0].words.startswith("touch 1: a point whose coordinates")


def test_fixed_npoint_asks_for_four_tips_then_offers_the_axes() -> None:
    tips = [next_role("fixed_npoint", [None] * k) for k in range(4)]
    assert all(t is not None and t.takes == "tip" and not t.enough for t in tips)
    assert tips[3] is not None
    assert "tip touch 4 of at least 4" in tips[3].words
    axes = next_role("fixed_npoint", [None] * 4, touch_noise_mm=NOISE_MM)
    assert axes is not None
    assert (axes.role, axes.enough) == ("origin", True)
    assert "or finish now" in axes.words
    started = next_role("fixed_npoint", [None] * 4 + ["origin"], touch_noise_mm=NOISE_MM)
    assert started is not None
    assert (started.role, started.enough) == ("x", False)
    assert next_role("fixed_npoint", [None] * 4 + ["origin", "x", "xy"]) is None


def test_manual_takes_no_touch() -> None:
    assert next_role("manual", []) is None
