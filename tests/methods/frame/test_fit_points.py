"""fit_points through its request model: 200 seeded frames noise-free to 1e-9, a gross touch
among six found and named, the reported sigma covering the truth, each refusal at its loc."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from app.errors import InvalidInput
from app.solvers.frame import interval_scale
from testbed.sim.cell_frames import FIXTURE_MM, touch_frame
from tests.methods.frame.bodies import angle_deg, context, coverage, nominal_body, refused, solve


def test_200_frames_noise_free_to_1e_9() -> None:
    rng = np.random.default_rng(47)
    worst_mm = worst_deg = 0.0
    for _ in range(200):
        touches = touch_frame(rng, FIXTURE_MM)
        body = nominal_body("fit_points", touches, options={"touch_noise_mm": 0.05})
        solved = solve(body, context(touches))
        worst_mm = max(worst_mm, float(np.abs(solved.position_mm - touches.frame_origin_mm).max()))
        worst_deg = max(worst_deg, angle_deg(solved.quaternion, touches.frame_rotation))
        assert solved.quality.outliers == []
    assert worst_mm < 1e-9
    assert worst_deg < 1e-9
    assert [f.name for f in solved.fiducials] == [f"touch_{i}" for i in range(1, 7)]
    np.testing.assert_allclose([f.nominal_mm for f in solved.fiducials], FIXTURE_MM)
    assert len(solved.quality.residuals_mm) == 6
    assert max(solved.quality.residuals_mm) < 1e-9


def test_one_gross_touch_among_six_is_found_and_named() -> None:
    rng = np.random.default_rng(53)
    for k in range(12):
        bad = k % 6
        touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05, gross={bad: 2.0})
        body = nominal_body("fit_points", touches, options={"touch_noise_mm": 0.05})
        solved = solve(body, context(touches))
        assert solved.quality.outliers == [bad]
        assert f"touch {bad + 1} set aside" in solved.warnings[0]
        assert solved.quality.residuals_mm[bad] > 1.0  # its residual is still reported
        assert f"touch_{bad + 1}" not in [f.name for f in solved.fiducials]
        assert np.abs(solved.position_mm - touches.frame_origin_mm).max() < 0.3


def test_the_noise_is_estimated_from_the_residuals_when_not_configured() -> None:
    rng = np.random.default_rng(54)
    touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05)
    solved = solve(nominal_body("fit_points", touches), context(touches))
    assert solved.quality.sigma_source == "residuals"
    assert solved.quality.interval95_scale == pytest.approx(interval_scale(3 * 6 - 6, 1))


def test_the_reported_sigma_covers_the_truth() -> None:
    """0.05 mm touches, a pointer TCP off by 0.02 mm (1-sigma) common to all six: each
    origin coordinate and small angle within its 95 % interval 93-97 % of the time."""
    share = coverage(
        4748, FIXTURE_MM, lambda t: nominal_body("fit_points", t, options={"touch_noise_mm": 0.05})
    )
    assert 0.93 <= share <= 0.97


def _refused(body, touches) -> InvalidInput:  # type: ignore[no-untyped-def]
    return refused(body, context(touches))


def test_nominal_points_in_inches_are_a_convention_mismatch_whose_suggestion_solves() -> None:
    rng = np.random.default_rng(57)
    touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05)
    in_inches = replace(touches, nominal_mm=FIXTURE_MM / 25.4)
    error = _refused(
        nominal_body("fit_points", in_inches, options={"touch_noise_mm": 0.05}), touches
    )
    assert (error.kind, error.loc) == ("convention-mismatch", ("touches",))
    assert "read in inch" in error.detail
    resent = replace(in_inches, nominal_mm=in_inches.nominal_mm * 25.4)
    solve(nominal_body("fit_points", resent, options={"touch_noise_mm": 0.05}), context(touches))


def test_nominal_points_that_fit_no_reading_name_the_worst_touch() -> None:
    rng = np.random.default_rng(58)
    touches = touch_frame(rng, FIXTURE_MM, touch_noise_mm=0.05)
    wrong = FIXTURE_MM.copy()
    wrong[4] += [0.0, 0.0, 30.0]
    wrong[5] += [20.0, 0.0, 0.0]
    body = nominal_body(
        "fit_points", replace(touches, nominal_mm=wrong), options={"touch_noise_mm": 0.05}
    )
    error = _refused(body, touches)
    assert error.kind == "rigid-misfit"
    assert error.loc[0] == "touches"
    assert error.loc[2] == "nominal_mm"
    assert f"touch {int(error.loc[1]) + 1} off by" in error.detail


def test_collinear_nominal_points_are_refused() -> None:
    line = np.array([[0.0, 0, 0], [100, 0, 0], [250, 0.3, 0], [400, 0, 0]])
    touches = touch_frame(np.random.default_rng(59), line)
    error = _refused(nominal_body("fit_points", touches, options={"touch_noise_mm": 0.05}), touches)
    assert (error.kind, error.loc) == ("collinear-points", ("touches",))
