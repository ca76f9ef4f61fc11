"""three_point (each convention) and four_point through their request models: 200 seeded
frames noise-free to 1e-9, the reported sigma covering the truth, and each refusal at the loc
of the touch to redo."""

from __future__ import annotations

from typing import get_args

import numpy as np
import pytest

from app.errors import InvalidInput
from app.solvers.frame import FOUR_POINT, THREE_POINT
from app.words import OriginXXy, UserMethodRole
from testbed.sim.cell_frames import touch_frame
from tests.methods.frame.bodies import angle_deg, context, coverage, refused, role_body, solve
from tests.solvers.test_frame import FOUR_NOMINAL, ROLE_NOMINAL

#: (method, convention, the roles' points in the frame) of every role construction.
CASES = [
    *[("three_point", name, ROLE_NOMINAL[name]) for name in THREE_POINT],
    ("four_point", None, FOUR_NOMINAL),
]


def _roles(method: str, convention: str | None) -> tuple[str, ...]:
    return THREE_POINT[convention].roles if method == "three_point" else FOUR_POINT.roles  # type: ignore[index]


def _body(method: str, convention: str | None, touches, order=None, **options):  # type: ignore[no-untyped-def]
    roles = list(_roles(method, convention))
    opts = {"touch_noise_mm": 0.05, **options}
    if convention is not None:
        opts["convention"] = convention
    return role_body(method, touches, roles, options=opts)


def test_the_words_roles_are_the_constructions() -> None:
    assert THREE_POINT["origin_x_xy"].roles == get_args(OriginXXy)
    assert THREE_POINT["ur_plane"].roles == get_args(OriginXXy)
    assert THREE_POINT["abb_user"].roles == get_args(UserMethodRole)


@pytest.mark.parametrize(("method", "convention", "nominal"), CASES)
def test_200_frames_noise_free_to_1e_9(method, convention, nominal) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(47)
    worst_mm = worst_deg = 0.0
    for _ in range(200):
        touches = touch_frame(rng, np.array(nominal))
        solved = solve(_body(method, convention, touches), context(touches))
        worst_mm = max(worst_mm, float(np.abs(solved.position_mm - touches.frame_origin_mm).max()))
        worst_deg = max(worst_deg, angle_deg(solved.quaternion, touches.frame_rotation))
    assert worst_mm < 1e-9
    assert worst_deg < 1e-9
    # the fiducials are the touched points in the new frame, named by role
    assert [f.name for f in solved.fiducials] == list(_roles(method, convention))
    np.testing.assert_allclose([f.nominal_mm for f in solved.fiducials], nominal, atol=1e-9)
    assert solved.tool is not None
    assert solved.tool.version == 1
    assert "mm from the origin is within" in solved.summary


def test_touches_in_any_order_give_the_same_frame() -> None:
    rng = np.random.default_rng(3)
    touches = touch_frame(rng, np.array(FOUR_NOMINAL))
    roles = list(FOUR_POINT.roles)
    order = [3, 1, 0, 2]
    from dataclasses import replace

    shuffled = replace(
        touches, rotations=touches.rotations[order], positions_mm=touches.positions_mm[order]
    )
    body = role_body(
        "four_point", shuffled, [roles[i] for i in order], options={"touch_noise_mm": 0.05}
    )
    solved = solve(body, context(touches))
    np.testing.assert_allclose(solved.position_mm, touches.frame_origin_mm, atol=1e-9)


def test_the_reported_sigma_covers_the_truth() -> None:
    """0.05 mm touches and a pointer TCP off by 0.02 mm (common to every touch): each origin
    coordinate and small angle within its 95 % interval 93-97 % of the time (400 sets)."""
    nominal = np.array(ROLE_NOMINAL["origin_x_xy"])
    share = coverage(4747, nominal, lambda t: _body("three_point", "origin_x_xy", t))
    assert 0.93 <= share <= 0.97


def _refused(body, touches) -> InvalidInput:  # type: ignore[no-untyped-def]
    return refused(body, context(touches))


def test_a_repeated_role_names_the_touch() -> None:
    touches = touch_frame(np.random.default_rng(5), np.array(ROLE_NOMINAL["origin_x_xy"]))
    error = _refused(
        role_body("three_point", touches, ["origin", "x", "x"], options={"touch_noise_mm": 0.05}),
        touches,
    )
    assert (error.kind, error.loc) == ("repeated-role", ("touches", 2, "role"))


def test_a_role_of_another_convention_is_named() -> None:
    touches = touch_frame(np.random.default_rng(5), np.array(ROLE_NOMINAL["origin_x_xy"]))
    error = _refused(
        role_body("three_point", touches, ["origin", "x", "y1"], options={"touch_noise_mm": 0.05}),
        touches,
    )
    assert (error.kind, error.loc) == ("missing-role", ("touches", 2, "role"))
    assert "xy" in str(error)


def test_a_missing_role_in_four_point_is_named() -> None:
    touches = touch_frame(np.random.default_rng(5), np.array(FOUR_NOMINAL))
    error = _refused(
        role_body(
            "four_point", touches, ["x_start", "x", "xy", "x"], options={"touch_noise_mm": 0.05}
        ),
        touches,
    )
    assert (error.kind, error.loc) == ("repeated-role", ("touches", 3, "role"))


def test_collinear_and_coincident_touches_name_the_touch_to_move() -> None:
    rng = np.random.default_rng(6)
    on_line = touch_frame(rng, np.array([[0.0, 0, 0], [400, 0, 0], [120, 0.2, 0]]))
    error = _refused(_body("three_point", "origin_x_xy", on_line), on_line)
    assert (error.kind, error.loc) == ("collinear-points", ("touches", 2))
    one_point = touch_frame(rng, np.array([[0.0, 0, 0], [0.3, 0, 0], [120, 300, 0]]))
    error = _refused(_body("three_point", "origin_x_xy", one_point), one_point)
    assert (error.kind, error.loc) == ("collinear-points", ("touches", 1))


def test_an_x_touch_too_close_names_the_distance_needed() -> None:
    touches = touch_frame(
        np.random.default_rng(7), np.array([[0.0, 0, 0], [30, 0, 0], [0, 300, 0]])
    )
    error = _refused(_body("three_point", "origin_x_xy", touches), touches)
    assert (error.kind, error.loc) == ("insufficient-spread", ("touches", 1))
    needed = error.context["needed_mm"]
    assert isinstance(needed, float)
    assert needed > 30
    assert f"at least {int(np.ceil(needed))} mm" in str(error)
    # touched that far, the same frame solves
    far = touch_frame(
        np.random.default_rng(7), np.array([[0.0, 0, 0], [np.ceil(needed) + 1, 0, 0], [0, 300, 0]])
    )
    solve(_body("three_point", "origin_x_xy", far), context(far))
    # a looser limit takes the near touch
    solve(_body("three_point", "origin_x_xy", touches, max_angle_sigma_deg=1.0), context(touches))


def test_no_touch_noise_is_refused_naming_where_to_set_it() -> None:
    touches = touch_frame(np.random.default_rng(8), np.array(ROLE_NOMINAL["origin_x_xy"]))
    body = role_body("three_point", touches, ["origin", "x", "xy"])
    error = _refused(body, touches)
    assert (error.kind, error.loc) == ("invalid-options", ("options", "touch_noise_mm"))
    from app.schemas.frame_tolerance import FrameTolerance

    solve(body, context(touches, tolerance=FrameTolerance(touch_noise_mm=0.05)))


def test_a_pointer_with_no_active_version_is_refused() -> None:
    from app.solvers.frame import Pointer
    from tests.methods.frame.given import GivenPointer

    touches = touch_frame(np.random.default_rng(9), np.array(ROLE_NOMINAL["origin_x_xy"]))
    ctx = GivenPointer({"pointer": {1: Pointer.of(touches.tcp_mm)}}, {"pointer": None})
    with pytest.raises(InvalidInput) as caught:
        solve(_body("three_point", "origin_x_xy", touches), ctx)
    assert (caught.value.kind, caught.value.loc) == ("unknown-reference", ("tool_id",))
    assert "calibrate it first" in str(caught.value)
    # a version named is used
    solved = solve({**_body("three_point", "origin_x_xy", touches), "tcp_version": 1}, ctx)
    assert solved.tool is not None
    assert solved.tool.version == 1


def test_an_unreadable_pose_is_refused_at_its_touch() -> None:
    touches = touch_frame(np.random.default_rng(10), np.array(ROLE_NOMINAL["origin_x_xy"]))
    body = _body("three_point", "origin_x_xy", touches)
    body["touches"][1]["pose"][3:] = [0.0, 0.0, 0.0, 0.0]
    error = _refused(body, touches)
    assert error.loc[:3] == ("touches", 1, "pose")
