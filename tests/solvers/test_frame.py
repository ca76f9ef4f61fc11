"""Frame solvers (app.solvers.frame) against simulated ground truth (testbed.sim.cell_frames):
noise-free to 1e-9, noisy against their own reported uncertainty, refusals that name the touch.

Each construction is also checked against one built here with numpy's cross products alone,
and its angles against scipy's Euler conversions in each maker's order, so that a mistake
shared by the project's construction and its pose conventions cannot pass."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.kinematics.poses import (
    fanuc_wpr_from_matrix,
    kuka_abc_from_matrix,
    matrix_from_fanuc_wpr,
    matrix_from_kuka_abc,
    quaternion_wxyz_from_matrix,
    rotvec_from_matrix,
)
from app.solvers.frame import (
    FOUR_POINT,
    THREE_POINT,
    FrameEstimate,
    construct,
    fit_points,
    fixed_tip,
    interval_scale,
    point_covariance,
    touch_points,
)
from testbed.sim.cell_frames import (
    FIXTURE_MM,
    FrameTouches,
    flange_rotations,
    random_frame,
    touch_frame,
)

#: Role points of a three-point teach in the frame's own coordinates (mm).
ROLE_NOMINAL = {
    "origin_x_xy": [[0.0, 0.0, 0.0], [400.0, 0.0, 0.0], [120.0, 300.0, 0.0]],
    "ur_plane": [[0.0, 0.0, 0.0], [400.0, 0.0, 0.0], [120.0, 300.0, 0.0]],
    # ABB: X1 and X2 on the X axis (X1 need not be the origin), Y1 on the +Y axis
    "abb_user": [[-80.0, 0.0, 0.0], [350.0, 0.0, 0.0], [0.0, 250.0, 0.0]],
}
FOUR_NOMINAL = [[-50.0, 20.0, 0.0], [350.0, 20.0, 0.0], [100.0, 300.0, 0.0], [0.0, 0.0, 0.0]]


def _angle_deg(R1: FloatArray, R2: FloatArray) -> float:
    return float(np.degrees(Rotation.from_matrix(R1.T @ R2).magnitude()))


def _solve_construction(touches, construction, sigma: float = 0.05, tcp_sigma: float = 0.0):  # type: ignore[no-untyped-def]
    points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
    C = point_covariance(touches.rotations, sigma, tcp_sigma**2 * np.eye(3))
    return construct(construction, list(construction.roles), points, C, touch_noise_mm=sigma)


def _fit_fixture(touches: FrameTouches) -> FrameEstimate:
    points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
    est = fit_points(FIXTURE_MM, points, touches.rotations, np.zeros((3, 3)), touch_noise_mm=0.05)
    assert est.outliers == ()
    return est


#: Each method with the points its touches reach (frame coordinates) and how it is solved.
NOISE_FREE: dict[str, tuple[FloatArray, Callable[[FrameTouches], FrameEstimate]]] = {
    **{
        f"three_point/{name}": (
            np.array(ROLE_NOMINAL[name]),
            partial(_solve_construction, construction=construction),
        )
        for name, construction in THREE_POINT.items()
    },
    "four_point": (np.array(FOUR_NOMINAL), partial(_solve_construction, construction=FOUR_POINT)),
    "fit_points": (FIXTURE_MM, _fit_fixture),
}


@pytest.mark.parametrize("method", list(NOISE_FREE))
def test_each_method_recovers_200_frames_noise_free(method: str) -> None:
    nominal, solve = NOISE_FREE[method]
    rng = np.random.default_rng(47)
    worst_mm = worst_deg = 0.0
    for _ in range(200):
        touches = touch_frame(rng, nominal)
        est = solve(touches)
        worst_mm = max(worst_mm, float(np.abs(est.origin_mm - touches.frame_origin_mm).max()))
        worst_deg = max(worst_deg, _angle_deg(est.rotation, touches.frame_rotation))
    assert worst_mm < 1e-9
    assert worst_deg < 1e-9


def _independent_three_point(o: FloatArray, x: FloatArray, xy: FloatArray) -> FloatArray:
    """The textbook construction with numpy alone: columns ex, ey, ez."""
    ex = (x - o) / np.sqrt(np.sum((x - o) ** 2))
    z = np.cross(ex, xy - o)
    ez = z / np.sqrt(np.sum(z**2))
    return np.stack([ex, np.cross(ez, ex), ez], axis=1)


def test_three_point_equals_an_independent_construction_in_each_makers_angles() -> None:
    """Random touched points (not from a known frame): the frame each pendant computes,
    built with numpy cross products, in KUKA A B C (Rz Ry Rx), FANUC/Yaskawa W P R
    (Rz(R) Ry(P) Rx(W)), ABB q1..q4 (w first) and UR's rotation vector, both ways, 1e-6."""
    rng = np.random.default_rng(50)
    construction = THREE_POINT["origin_x_xy"]
    for _ in range(200):
        o, x, xy = rng.uniform(-900, 900, size=(3, 3))
        expected = _independent_three_point(o, x, xy)
        C = np.eye(9) * 0.0025
        est = construct(
            construction,
            ["origin", "x", "xy"],
            np.array([o, x, xy]),
            C,
            touch_noise_mm=0.05,
            max_angle_sigma_deg=180.0,
        )
        np.testing.assert_allclose(est.rotation, expected, atol=1e-12)
        np.testing.assert_allclose(est.origin_mm, o, atol=1e-12)
        a, b, c = Rotation.from_matrix(expected).as_euler("ZYX", degrees=True)
        np.testing.assert_allclose(kuka_abc_from_matrix(est.rotation), [a, b, c], atol=1e-6)
        np.testing.assert_allclose(fanuc_wpr_from_matrix(est.rotation), [c, b, a], atol=1e-6)
        np.testing.assert_allclose(matrix_from_kuka_abc([a, b, c]), expected, atol=1e-6)
        np.testing.assert_allclose(matrix_from_fanuc_wpr([c, b, a]), expected, atol=1e-6)
        qx, qy, qz, qw = Rotation.from_matrix(expected).as_quat()
        q = np.array([qw, qx, qy, qz]) * (1 if qw >= 0 else -1)
        np.testing.assert_allclose(quaternion_wxyz_from_matrix(est.rotation), q, atol=1e-6)
        np.testing.assert_allclose(est.quaternion_wxyz, q, atol=1e-6)
        np.testing.assert_allclose(
            rotvec_from_matrix(est.rotation), Rotation.from_matrix(expected).as_rotvec(), atol=1e-6
        )


def test_abb_user_method_puts_the_origin_where_y1_meets_the_x_axis() -> None:
    """DefFrame(X1, X2, Y1 \\Origin:=3): the origin is on the line X1-X2 with Y1 on the y axis,
    not at X1: built here from the foot of the perpendicular, numpy alone."""
    x1, x2, y1 = (
        np.array([100.0, 50.0, 10.0]),
        np.array([600.0, 60.0, 12.0]),
        np.array([300.0, 400.0, 9.0]),
    )
    ex = (x2 - x1) / np.linalg.norm(x2 - x1)
    foot = x1 + np.dot(y1 - x1, ex) * ex
    est = construct(
        THREE_POINT["abb_user"],
        ["x1", "x2", "y1"],
        np.array([x1, x2, y1]),
        np.eye(9) * 0.0025,
        touch_noise_mm=0.05,
    )
    np.testing.assert_allclose(est.origin_mm, foot, atol=1e-9)
    np.testing.assert_allclose(
        est.rotation[:, 1], (y1 - foot) / np.linalg.norm(y1 - foot), atol=1e-12
    )
    assert np.linalg.norm(est.origin_mm - x1) > 100.0  # and so not the KUKA origin


def _coverage(estimates: list[tuple[FrameEstimate, FloatArray, FloatArray]]) -> dict[str, float]:
    """Share of sets whose truth lies within the 95 % interval, per component and for the
    origin's 3-D ellipsoid; and RMS error / Cramer-Rao bound (the reported covariance)."""
    k1, k3 = interval_scale(None, 1), interval_scale(None, 3)
    inside = np.zeros(6)
    ellipsoid = 0
    err2 = np.zeros(6)
    bound2 = np.zeros(6)
    for est, R, o in estimates:
        e = np.concatenate(
            [est.origin_mm - o, Rotation.from_matrix(R.T @ est.rotation).as_rotvec()]
        )
        sd = np.sqrt(np.diag(est.covariance))
        inside += np.abs(e) <= k1 * sd
        ellipsoid += float(e[:3] @ np.linalg.solve(est.covariance[:3, :3], e[:3])) <= k3**2
        err2 += e**2
        bound2 += sd**2
    n = len(estimates)
    return {
        "min_component": float(inside.min() / n),
        "max_component": float(inside.max() / n),
        "ellipsoid": ellipsoid / n,
        "rms_over_bound": float(np.sqrt(err2.sum() / bound2.sum())),
    }


def test_fit_points_noisy_error_at_the_bound_and_intervals_cover_95_percent() -> None:
    """0.05 mm touches, a pointer TCP with 0.02 mm sigma (shared by every touch of a set):
    1000 seeded sets; the RMS error is within 1.1x of the bound the solver reports (which is
    the Cramer-Rao bound of the correlated model), and 95 % intervals cover 93-97 %."""
    rng = np.random.default_rng(51)
    estimates = []
    tcp_cov = 0.02**2 * np.eye(3)
    for _ in range(1000):
        touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05, tcp_sigma_mm=0.02, tilt_deg=35)
        points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
        est = fit_points(FIXTURE_MM, points, touches.rotations, tcp_cov, touch_noise_mm=0.05)
        estimates.append((est, touches.frame_rotation, touches.frame_origin_mm))
    figures = _coverage(estimates)
    assert figures["min_component"] >= 0.93, figures
    assert figures["max_component"] <= 0.97, figures
    assert 0.93 <= figures["ellipsoid"] <= 0.97, figures
    assert figures["rms_over_bound"] <= 1.1, figures


def test_the_pointers_tcp_error_is_propagated_not_taken_as_independent() -> None:
    """With the TCP error dominant (0.5 mm) and every touch in one orientation, it shifts the
    whole frame: the origin's sigma carries it in full (about 0.5 mm), which independent
    noise of 0.5 mm per touch over six touches would have cut to about 0.2 mm."""
    rng = np.random.default_rng(52)
    touches = touch_frame(rng, FIXTURE_MM, tilt_deg=0.0)
    points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
    est = fit_points(FIXTURE_MM, points, touches.rotations, 0.25 * np.eye(3), touch_noise_mm=0.01)
    assert est.position_sigma_mm.min() > 0.49
    assert est.angle_sigma_deg.max() < 0.01  # a common shift turns nothing


def test_one_gross_touch_among_six_is_found_and_named() -> None:
    rng = np.random.default_rng(53)
    named = []
    for k in range(20):
        bad = k % 6
        touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05, gross={bad: 2.0})
        points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
        est = fit_points(
            FIXTURE_MM, points, touches.rotations, np.zeros((3, 3)), touch_noise_mm=0.05
        )
        named.append(est.outliers == (bad,))
        assert f"touch {bad + 1} set aside" in est.warnings[0]
        assert np.abs(est.origin_mm - touches.frame_origin_mm).max() < 0.3
    assert all(named)


def test_one_gross_touch_is_found_with_the_noise_estimated() -> None:
    rng = np.random.default_rng(54)
    nominal = np.vstack([FIXTURE_MM, [[400.0, 100.0, 10.0], [50.0, 150.0, 5.0]]])
    touches = touch_frame(rng, nominal, touch_noise_mm=0.05, gross={3: 1.5})
    points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
    est = fit_points(nominal, points, touches.rotations, np.zeros((3, 3)), touch_noise_mm=None)
    assert est.outliers == (3,)
    assert est.sigma_source == "residuals"
    assert est.dof == 3 * 7 - 6
    assert 0.02 < est.touch_noise_mm < 0.1


def test_clean_touches_set_nothing_aside() -> None:
    """No false alarm: 200 clean sets of six with configured noise, none set aside."""
    rng = np.random.default_rng(55)
    flagged = 0
    for _ in range(200):
        touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05)
        points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
        est = fit_points(
            FIXTURE_MM, points, touches.rotations, np.zeros((3, 3)), touch_noise_mm=0.05
        )
        flagged += bool(est.outliers)
    assert flagged <= 3  # alpha 1 % over the whole set: expected 2 of 200


def test_the_worst_point_over_the_extent_grows_with_the_distance() -> None:
    rng = np.random.default_rng(56)
    touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05, tcp_sigma_mm=0.02)
    points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
    est = fit_points(
        FIXTURE_MM, points, touches.rotations, 0.02**2 * np.eye(3), touch_noise_mm=0.05
    )
    reach, worst = est.extent()
    assert reach == pytest.approx(math.hypot(500.0, 300.0))
    assert worst >= est.point_error_95_mm([0.0, 0.0, 0.0])
    assert worst >= est.point_error_95_mm([500.0, 300.0, 0.0]) - 1e-12
    assert 0.02 < worst < 0.5


# ---------------------------------------------------------------------------------------
# Refusals
# ---------------------------------------------------------------------------------------


def _refusal(roles: list[str], points: list[list[float]], **kw: Any) -> InvalidInput:
    n = len(points)
    with pytest.raises(InvalidInput) as caught:
        construct(
            THREE_POINT["origin_x_xy"],
            roles,
            np.array(points, dtype=float),
            np.eye(3 * n) * 0.0025,
            touch_noise_mm=0.05,
            **kw,
        )
    return caught.value


def test_a_missing_role_is_named() -> None:
    error = _refusal(["origin", "x", "x"], [[0, 0, 0], [300, 0, 0], [400, 0, 0]])
    assert error.kind == "repeated-role"
    assert error.loc == ("touches", 2, "role")
    assert "touches 2 and 3 both have role 'x'" in error.detail
    error = _refusal(["origin", "x"], [[0, 0, 0], [300, 0, 0]])
    assert error.kind == "missing-role"
    assert "'xy'" in error.detail
    assert "+Y side" in error.detail
    error = _refusal(["origin", "x", "y"], [[0, 0, 0], [300, 0, 0], [0, 300, 0]])
    assert error.kind == "missing-role"
    assert error.loc == ("touches", 2, "role")


def test_coincident_and_collinear_points_are_refused() -> None:
    error = _refusal(["origin", "x", "xy"], [[0, 0, 0], [0.3, 0, 0], [0, 300, 0]])
    assert error.kind == "collinear-points"
    assert "0.300 mm" in error.detail
    error = _refusal(["origin", "x", "xy"], [[0, 0, 0], [300, 0, 0], [600, 0.2, 0]])
    assert error.kind == "collinear-points"
    assert "one line" in error.detail


def test_an_x_touch_too_close_names_the_distance_needed() -> None:
    """0.05 mm touches, X 30 mm away: about 0.135 deg (METHODS.md: 0.13 deg), more than the
    0.05 deg default; the refusal says how far: sqrt(2) 0.05 / 0.05 deg in rad = 81.03 mm."""
    error = _refusal(["origin", "x", "xy"], [[0, 0, 0], [30, 0, 0], [0, 300, 0]])
    assert error.kind == "insufficient-spread"
    assert error.context["angle_sigma_deg"] == pytest.approx(
        math.degrees(math.sqrt(2) * 0.05 / 30), rel=1e-4
    )
    assert "at least 82 mm" in error.detail
    assert "30.0 mm" in error.detail
    ok = construct(
        THREE_POINT["origin_x_xy"],
        ["origin", "x", "xy"],
        np.array([[0, 0, 0], [82, 0, 0], [0, 300, 0]], float),
        np.eye(9) * 0.0025,
        touch_noise_mm=0.05,
    )
    assert ok.angle_sigma_deg.max() <= 0.05
    at_250 = _solve_at(250.0)
    assert at_250 == pytest.approx(0.0162, abs=2e-4)  # METHODS.md: about 0.016 deg


def _solve_at(distance: float) -> float:
    est = construct(
        THREE_POINT["origin_x_xy"],
        ["origin", "x", "xy"],
        np.array([[0, 0, 0], [distance, 0, 0], [0, 300, 0]], float),
        np.eye(9) * 0.0025,
        touch_noise_mm=0.05,
    )
    return float(est.angle_sigma_deg[2])


def test_nominal_points_in_inches_get_a_suggestion_that_solves() -> None:
    rng = np.random.default_rng(57)
    touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05)
    points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
    for given, words in [
        (FIXTURE_MM / 25.4, "read in inch"),
        (FIXTURE_MM[:, [1, 0, 2]], "mirrored: two of the drawing's axes swapped"),
        (FIXTURE_MM * [1.0, -1.0, 1.0], "or one of them negated"),
        (FIXTURE_MM[[1, 0, 2, 3, 4, 5]], "touches 2, 1, 3, 4, 5, 6"),
    ]:
        with pytest.raises(InvalidInput) as caught:
            fit_points(given, points, touches.rotations, np.zeros((3, 3)), touch_noise_mm=0.05)
        assert caught.value.kind == "convention-mismatch", caught.value
        assert words in caught.value.detail
        assert caught.value.members["suggestion"]["rms_mm"] < 0.5  # type: ignore[index]


def test_nominal_points_that_fit_no_reading_name_the_worst_touch() -> None:
    rng = np.random.default_rng(58)
    touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05)
    points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
    wrong = FIXTURE_MM.copy()
    wrong[4] += [0.0, 0.0, 30.0]
    wrong[5] += [20.0, 0.0, 0.0]
    with pytest.raises(InvalidInput) as caught:
        fit_points(wrong, points, touches.rotations, np.zeros((3, 3)), touch_noise_mm=0.05)
    assert caught.value.kind == "rigid-misfit"
    assert caught.value.loc[:1] == ("touches",)
    assert caught.value.loc[2] == "nominal_mm"


def test_collinear_nominal_points_are_refused() -> None:
    line = np.array([[0.0, 0, 0], [100, 0, 0], [250, 0.3, 0], [400, 0, 0]])
    rng = np.random.default_rng(59)
    touches = touch_frame(rng, line)
    points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
    with pytest.raises(InvalidInput) as caught:
        fit_points(line, points, touches.rotations, np.zeros((3, 3)), touch_noise_mm=0.05)
    assert caught.value.kind == "collinear-points"


# ---------------------------------------------------------------------------------------
# Fixed tools
# ---------------------------------------------------------------------------------------


def test_a_fixed_tool_tip_and_the_pointers_tcp_from_8_touches() -> None:
    """8 touches of a stationary tip by a pointer with an unknown TCP: the tip and the
    pointer's TCP, both recovered noise-free (far within 0.01 mm)."""
    rng = np.random.default_rng(60)
    for _ in range(50):
        tip = rng.uniform(-600, 600, size=3)
        tcp = np.array([3.0, -4.0, 160.0]) + rng.normal(0, 5, size=3)
        R = flange_rotations(rng, 8, 40.0)
        f = tip - np.einsum("nij,j->ni", R, tcp)
        found = fixed_tip(R, f, align={"z": "-z"})
        np.testing.assert_allclose(found.tip_mm, tip, atol=1e-9)
        np.testing.assert_allclose(found.pointer.tcp_mm, tcp, atol=1e-9)
        np.testing.assert_allclose(found.rotation[:, 2], [0, 0, -1], atol=1e-12)


def test_a_fixed_tool_tip_with_noise_is_within_its_reported_uncertainty() -> None:
    rng = np.random.default_rng(61)
    inside = 0
    k = interval_scale(None, 3)
    for _ in range(400):
        tip = rng.uniform(-600, 600, size=3)
        tcp = np.array([3.0, -4.0, 160.0])
        R = flange_rotations(rng, 8, 40.0)
        f = tip - np.einsum("nij,j->ni", R, tcp) + rng.normal(0, 0.05, size=(8, 3))
        found = fixed_tip(R, f, touch_noise_mm=0.05)
        e = found.tip_mm - tip
        inside += float(e @ np.linalg.solve(found.tip_covariance_mm2, e)) <= k**2
    assert 0.93 <= inside / 400 <= 0.97 + 0.02  # 400 sets: a 2 % margin of binomial spread
    assert np.allclose(found.rotation, np.eye(3))  # no align: the base frame's axes


def test_random_frames_are_proper_rotations() -> None:
    rng = np.random.default_rng(62)
    R, _ = random_frame(rng)
    assert np.linalg.det(R) == pytest.approx(1.0)
