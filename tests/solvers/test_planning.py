"""The planner: its A-optimal sets beat random ones in the same cone, its prediction is what a
simulated operator achieves, it is deterministic, and it picks the fewest touches for a target."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.kinematics.touchsets import cone_rotations, flange_positions, random_cone_rotations
from app.solvers.npoint import solve_npoint
from app.solvers.planning import (
    MAX_TOUCHES,
    Cone,
    next_touch,
    plan_touches,
    relative_rotations,
    smallest_plan,
    tilt_lean_spin,
    unit_covariance,
)

START = Rotation.from_euler("x", 180.0, degrees=True)
CONE = Cone(40.0, 90.0)


def test_planned_six_touches_beat_the_median_random_set_by_at_least_a_fifth() -> None:
    plan = plan_touches(6, CONE)
    predicted = np.sqrt(np.trace(plan.unit_covariance))
    rng = np.random.default_rng(1)
    random = [
        np.sqrt(np.trace(unit_covariance(r.as_matrix())))
        for r in (
            random_cone_rotations(rng, 6, START, max_tilt_deg=40.0, max_spin_deg=90.0)
            for _ in range(500)
        )
    ]
    ratio = predicted / np.median(random)
    assert ratio <= 0.8, ratio
    assert ratio > 0.5  # no better than the physics allows (the bench finds 0.63)
    assert np.all(plan.tilt_deg <= 40.0 + 1e-9)
    assert np.all(np.abs(plan.spin_deg) <= 90.0 + 1e-9)


def test_what_a_simulated_operator_achieves_is_what_the_plan_predicts() -> None:
    noise = 0.02
    plan = plan_touches(6, CONE)
    rotations = cone_rotations(START, plan.tilt_deg, plan.azimuth_deg, plan.spin_deg)
    rng = np.random.default_rng(2)
    squared = []
    for _ in range(200):
        tcp = np.array([0.0, 0.0, 150.0]) + rng.normal(0.0, 20.0, 3)
        point = np.array([800.0, 0.0, 250.0]) + rng.normal(0.0, 50.0, 3)
        f = flange_positions(rotations, tcp, point) + rng.normal(0.0, noise, (6, 3))
        result = solve_npoint(rotations.as_matrix(), f, touch_noise_mm=noise)
        squared.append(np.sum((result.tcp_mm - tcp) ** 2))
    achieved = np.sqrt(np.mean(squared))
    assert 0.85 <= achieved / plan.total_sigma_mm(noise) <= 1.2, achieved


def test_plans_are_deterministic_and_the_target_picks_the_fewest_touches() -> None:
    a, b = plan_touches(7, CONE), plan_touches(7, CONE)
    assert np.array_equal(a.tilt_deg, b.tilt_deg)
    assert np.array_equal(a.spin_deg, b.spin_deg)
    chosen = smallest_plan(0.01, 0.02, CONE)
    assert chosen is not None
    n = chosen.tilt_deg.size
    assert chosen.total_sigma_mm(0.02) <= 0.01
    assert plan_touches(n - 1, CONE).total_sigma_mm(0.02) > 0.01
    assert smallest_plan(0.001, 0.02, CONE) is None
    assert plan_touches(MAX_TOUCHES, CONE).total_sigma_mm(0.02) > 0.001


def test_a_cone_without_tilt_or_spin_cannot_determine_the_tcp() -> None:
    plan = plan_touches(6, Cone(0.0, 0.0))
    assert not np.all(np.isfinite(plan.unit_covariance))


def test_next_touch_opens_the_weakest_direction() -> None:
    # Three touches tilted about flange x only: the TCP is weak where y-tilts would help;
    # the next touch must tilt towards an azimuth that adds it, and improve the worst axis.
    done = relative_rotations(
        np.array([0.0, 40.0, 40.0]), np.array([0.0, 90.0, 270.0]), np.zeros(3)
    )
    tilt, azimuth, spin = next_touch(done, CONE)
    after = np.concatenate(
        [done, relative_rotations(np.array([tilt]), np.array([azimuth]), np.array([spin]))]
    )
    before_info = np.linalg.eigvalsh(3 * (np.eye(3) - done.mean(0).T @ done.mean(0)))[0]
    after_info = np.linalg.eigvalsh(4 * (np.eye(3) - after.mean(0).T @ after.mean(0)))[0]
    assert after_info > before_info + 0.1
    assert 0.0 < tilt <= 40.0


def test_tilt_lean_spin_reads_back_the_planners_tilt_azimuth_and_spin() -> None:
    """A touch T = Rot(a, tilt) Rz(spin), a at `azimuth` in the x-y plane, leans its tool axis
    toward azimuth - 90 deg; its tilt and spin come back as given, from any first pose."""
    first = Rotation.from_euler("xyz", [170.0, 12.0, -40.0], degrees=True).as_matrix()
    for tilt, azimuth, spin in [(30.0, 0.0, 45.0), (12.5, 135.0, -90.0), (40.0, 290.0, 170.0)]:
        relative = relative_rotations(np.array([tilt]), np.array([azimuth]), np.array([spin]))[0]
        got = tilt_lean_spin(first, first @ relative)
        assert got == pytest.approx((tilt, (azimuth - 90.0) % 360.0, spin), abs=1e-9)
    assert tilt_lean_spin(first, first) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)
