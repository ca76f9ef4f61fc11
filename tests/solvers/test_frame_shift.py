"""Re-registration after a move (app.solvers.frame.shift): the shift of a fixture found from
its stored fiducials touched again, against simulated moves (testbed.sim.cell_frames)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.solvers.distributions import chi2_ppf
from app.solvers.frame import touch_points
from app.solvers.frame.shift import check_near, shift_from_fiducials
from testbed.sim.cell_frames import FIXTURE_MM, random_frame, touch_frame


def _moved(rng: np.random.Generator, mm: float, deg: float):  # type: ignore[no-untyped-def]
    axis = rng.normal(size=3)
    dR = Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.radians(deg)).as_matrix()
    direction = rng.normal(size=3)
    return dR, mm * direction / np.linalg.norm(direction)


def test_a_moved_fixture_is_found_and_its_frame_corrected_noise_free() -> None:
    """A fixture moved by 1.5 mm and 0.3 deg (up to about 4 mm at a point 500 mm out): the
    corrected frame within 1e-9 of where it now is, each fiducial's deviation as it moved."""
    rng = np.random.default_rng(49)
    for _ in range(100):
        R0, o0 = random_frame(rng)
        dR, dt = _moved(rng, 1.5, 0.3)
        R1, o1 = dR @ R0, dR @ o0 + dt
        stored = FIXTURE_MM @ R0.T + o0
        touches = touch_frame(rng, FIXTURE_MM, frame=(R1, o1))
        points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
        shift = shift_from_fiducials(
            stored, R0, points, touches.rotations, np.zeros((3, 3)), touch_noise_mm=0.05
        )
        R, o = shift.moved(R0, o0)
        np.testing.assert_allclose(R, R1, atol=1e-12)
        np.testing.assert_allclose(o, o1, atol=1e-9)
        np.testing.assert_allclose(shift.deviations_mm, (points - stored) @ R0, atol=1e-9)
        assert shift.angle_deg == pytest.approx(0.3, abs=1e-9)
        truth = np.linalg.norm(FIXTURE_MM @ R1.T + o1 - stored, axis=1)
        np.testing.assert_allclose(shift.distances_mm, truth, atol=1e-9)


def test_the_shifts_95_percent_region_covers_the_truth_over_500_moves() -> None:
    """0.05 mm touches, a pointer TCP with 0.02 mm sigma: the shift's 6-D 95 % region (its
    covariance, chi-squared with 6 dof) holds the true move 93-97 % of the time."""
    rng = np.random.default_rng(50)
    k2 = chi2_ppf(0.95, 6)
    inside = 0
    for _ in range(500):
        R0, o0 = random_frame(rng)
        dR, dt = _moved(rng, rng.uniform(0.5, 5.0), rng.uniform(0.0, 0.5))
        stored = FIXTURE_MM @ R0.T + o0
        touches = touch_frame(
            rng, FIXTURE_MM, frame=(dR @ R0, dR @ o0 + dt), touch_noise_mm=0.05, tcp_sigma_mm=0.02
        )
        points = touch_points(touches.rotations, touches.positions_mm, touches.tcp_mm)
        shift = shift_from_fiducials(
            stored, R0, points, touches.rotations, 0.02**2 * np.eye(3), touch_noise_mm=0.05
        )
        # the estimate's error in its own parameters: translation, rotation after dR
        e = np.concatenate(
            [shift.translation_mm - dt, Rotation.from_matrix(dR.T @ shift.rotation).as_rotvec()]
        )
        inside += float(e @ np.linalg.solve(shift.fit.covariance, e)) <= k2
    assert 0.93 <= inside / 500 <= 0.97


def test_a_touch_far_from_its_fiducial_is_refused_naming_the_one_it_is_near() -> None:
    stored = FIXTURE_MM.copy()
    names = ["a", "b", "c", "d", "e", "f"]
    touched = stored[[0, 1, 3]] + 0.4
    with pytest.raises(InvalidInput) as caught:
        check_near(["a", "b", "c"], stored, names, touched, max_distance_mm=7.0)
    assert caught.value.loc == ("touches", 2, "fiducial")
    assert "fiducial 'd'" in caught.value.detail
    far = touched.copy()
    far[1] += [0.0, 0.0, 120.0]
    with pytest.raises(InvalidInput) as caught:
        check_near(["a", "b", "d"], stored, names, far, max_distance_mm=7.0)
    assert caught.value.loc == ("touches", 1, "fiducial")
    assert "another frame" in caught.value.detail
    check_near(["a", "b", "d"], stored, names, touched, max_distance_mm=7.0)  # near: passes


def test_a_fiducial_the_frame_does_not_have_is_refused_naming_those_it_has() -> None:
    with pytest.raises(InvalidInput) as caught:
        check_near(["a", "z"], FIXTURE_MM[:2], ["a", "b"], FIXTURE_MM[:2], max_distance_mm=7.0)
    assert caught.value.loc == ("touches", 1, "fiducial")
    assert "'z', which this frame does not have: its fiducials are 'a', 'b'" in caught.value.detail


def test_fewer_than_three_fiducials_are_refused() -> None:
    with pytest.raises(InvalidInput) as caught:
        shift_from_fiducials(
            FIXTURE_MM[:2],
            np.eye(3),
            FIXTURE_MM[:2],
            np.tile(np.eye(3), (2, 1, 1)),
            np.zeros((3, 3)),
            touch_noise_mm=0.05,
        )
    assert caught.value.kind == "too-few-poses"
