"""xyz_plane's solver (METHODS 7): exact on exact data, honest intervals, named refusals."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.solvers.plane import solve_plane
from testbed.sim.planes import simulate_plane_touches
from testbed.sim.touches import TOOL_DOWN


@pytest.mark.parametrize(("planes", "n"), [(1, 7), (1, 12), (2, 12), (3, 18)])
def test_noise_free_touches_give_the_tcp_and_planes_exactly(planes: int, n: int) -> None:
    for seed in range(5):
        sim = simulate_plane_touches(n, seed=seed, planes=planes, touch_noise_mm=0.0)
        result = solve_plane(sim.R, sim.f, planes=sim.labels, touch_noise_mm=0.05)
        assert_allclose(result.tcp_mm, sim.t, atol=1e-9)
        for k, plane in enumerate(result.planes):
            sign = np.sign(plane.normal @ sim.normals[k])
            assert_allclose(sign * plane.normal, sim.normals[k], atol=1e-12)
            assert plane.offset_mm == pytest.approx(sign * sim.offsets[k], abs=1e-9)
        assert result.quality.rms_mm < 1e-9


def test_starting_from_the_active_tcp_or_from_zero_gives_the_same_answer() -> None:
    sim = simulate_plane_touches(10, seed=7, touch_noise_mm=0.05)
    a = solve_plane(sim.R, sim.f)
    b = solve_plane(sim.R, sim.f, start_tcp_mm=sim.t + np.array([3.0, -2.0, 10.0]))
    assert_allclose(a.tcp_mm, b.tcp_mm, atol=1e-8)


def test_95_percent_intervals_cover_the_truth_95_percent_of_the_time() -> None:
    """1000 seeded sets, the noise estimated from the residuals (on N - 6 = 2 degrees of
    freedom, the interval widened by Student's t): the true TCP lies within +-1.96 reported
    sigma on 93-97 % of the axes and inside the reported 95 % ellipsoid in 93-97 % of the
    sets. (With the noise configured: bench/accuracy.py's plane rows.)"""
    axis_hits = ellipsoid_hits = 0
    trials = 1000
    for k in range(trials):
        sim = simulate_plane_touches(8, seed=50_000 + k, tilt_deg=45.0, touch_noise_mm=0.05)
        result = solve_plane(sim.R, sim.f)
        err = result.tcp_mm - sim.t
        sigma = np.asarray(result.quality.tcp_sigma_mm)
        axis_hits += int(np.sum(np.abs(err) <= 1.96 * sigma))
        cov = np.asarray(result.quality.tcp_covariance_mm2)
        d2 = float(err @ np.linalg.solve(cov, err))
        ellipsoid_hits += int(d2 <= result.quality.ellipsoid95_scale**2)
    assert 0.93 <= axis_hits / (3 * trials) <= 0.97, axis_hits
    assert 0.93 <= ellipsoid_hits / trials <= 0.97, ellipsoid_hits


def test_the_tool_axis_is_the_least_certain_component() -> None:
    """METHODS 7: with the tool roughly normal to the plane, the TCP along the tool axis is
    told from the plane's offset only by the spread of cos(tilt)."""
    sim = simulate_plane_touches(12, seed=3, tilt_deg=30.0, tcp_mm=np.array([0.0, 0.0, 200.0]))
    sigma = solve_plane(sim.R, sim.f, touch_noise_mm=0.05).quality.tcp_sigma_mm
    assert sigma[2] > 2.0 * max(sigma[0], sigma[1])


def _positions(R: np.ndarray, t: np.ndarray, points: np.ndarray) -> np.ndarray:
    return np.asarray(points - R @ t)


def _points_on_floor(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(700, 900, n), rng.uniform(-250, -50, n), np.full(n, 250.0)])


TCP = np.array([2.0, -1.0, 160.0])


def test_pure_translations_are_refused_naming_the_tilt_to_add() -> None:
    R = np.repeat(TOOL_DOWN.as_matrix()[None], 8, axis=0)
    f = _positions(R, TCP, _points_on_floor(8))
    with pytest.raises(InvalidInput) as caught:
        solve_plane(R, f)
    assert caught.value.kind == "degenerate-poses"
    assert "only translate" in caught.value.detail
    assert "tilted in different directions" in caught.value.detail


def test_parallel_tool_axes_are_refused_naming_the_tool_axis() -> None:
    """The issue's degenerate set: every touch with the tool axis parallel (turned only about
    flange z), on a tilted plane so that it is not a spin about the normal."""
    spins = Rotation.from_euler("z", np.linspace(-150, 150, 8)[:, None], degrees=True)
    tilted = Rotation.from_euler("y", 20, degrees=True) * TOOL_DOWN
    R = (tilted * spins).as_matrix()
    f = _positions(R, TCP, _points_on_floor(8))
    with pytest.raises(InvalidInput) as caught:
        solve_plane(R, f, touch_noise_mm=0.05)
    assert caught.value.kind == "degenerate-poses"
    assert "parallel tool axes" in caught.value.detail
    assert "tilt the tool about another axis" in caught.value.detail
    assert caught.value.loc == ("poses",)


def test_spins_about_the_plane_normal_are_refused_naming_the_tilt() -> None:
    tilt = Rotation.from_euler("x", 25, degrees=True)
    R = (
        Rotation.from_euler("z", np.linspace(-150, 150, 8)[:, None], degrees=True)
        * tilt
        * TOOL_DOWN
    )
    R_m = R.as_matrix()
    f = _positions(R_m, TCP, _points_on_floor(8))
    with pytest.raises(InvalidInput) as caught:
        solve_plane(R_m, f, touch_noise_mm=0.05)
    assert caught.value.kind == "degenerate-poses"
    assert "spin the tool about the plane's normal" in caught.value.detail
    assert "tilt the tool relative to the plane" in caught.value.detail


def test_touches_at_one_spot_are_refused_naming_the_plane() -> None:
    sim = simulate_plane_touches(10, seed=1, spread_mm=0.0, touch_noise_mm=0.0)
    with pytest.raises(InvalidInput) as caught:
        solve_plane(sim.R, sim.f, touch_noise_mm=0.05)
    assert caught.value.kind == "degenerate-poses"
    assert "plane 'a'" in caught.value.detail
    assert "spread across the plane" in caught.value.detail


def test_six_touches_are_refused_as_several_exact_solutions() -> None:
    """6 touches fit the 6 unknowns exactly, at several solutions: one more is asked for."""
    sim = simulate_plane_touches(6, seed=1)
    for noise in (None, 0.05):
        with pytest.raises(InvalidInput) as caught:
            solve_plane(sim.R, sim.f, touch_noise_mm=noise)
        assert caught.value.kind == "too-few-poses"
        assert "at least 7" in caught.value.detail
        assert "several exact solutions" in caught.value.detail


def test_two_planes_need_ten_touches() -> None:
    sim = simulate_plane_touches(9, seed=1, planes=2)
    with pytest.raises(InvalidInput) as caught:
        solve_plane(sim.R, sim.f, planes=sim.labels, touch_noise_mm=0.05)
    assert "at least 10" in caught.value.detail


def test_a_plane_with_too_few_touches_is_named() -> None:
    sim = simulate_plane_touches(12, seed=2, planes=2)
    labels = ["a"] * 10 + ["b"] * 2
    with pytest.raises(InvalidInput) as caught:
        solve_plane(sim.R, sim.f, planes=labels, touch_noise_mm=0.05)
    assert caught.value.kind == "too-few-poses"
    assert "plane 'b' has 2 touch(es)" in caught.value.detail
    assert caught.value.loc == ("poses", 10, "plane")


def test_labelled_planes_share_the_tcp_and_each_get_their_own_normal() -> None:
    sim = simulate_plane_touches(18, seed=11, planes=3, touch_noise_mm=0.02)
    result = solve_plane(sim.R, sim.f, planes=sim.labels)
    assert [p.label for p in result.planes] == ["a", "b", "c"]
    assert [p.n_touches for p in result.planes] == [6, 6, 6]
    sigma = np.asarray(result.quality.tcp_sigma_mm)
    assert np.all(np.abs(result.tcp_mm - sim.t) <= 4.0 * sigma)
    for k, plane in enumerate(result.planes):
        angle = np.degrees(np.arccos(min(1.0, abs(float(plane.normal @ sim.normals[k])))))
        assert angle <= 4.0 * plane.normal_sigma_deg + 1e-9


def test_a_wrong_configured_noise_is_flagged() -> None:
    sim = simulate_plane_touches(12, seed=4, tilt_deg=40.0, touch_noise_mm=0.2)
    result = solve_plane(sim.R, sim.f, touch_noise_mm=0.01)
    assert any("larger than the configured touch noise" in w for w in result.quality.warnings)
    assert any("touch #" in w for w in result.quality.warnings)


def test_a_weak_set_is_refused_against_the_allowed_sigma() -> None:
    sim = simulate_plane_touches(8, seed=5, tilt_deg=5.0, touch_noise_mm=0.05)
    with pytest.raises(InvalidInput) as caught:
        solve_plane(sim.R, sim.f, touch_noise_mm=0.05, max_tcp_sigma_mm=0.5)
    assert caught.value.kind == "insufficient-spread"
    assert "tilt the tool further" in caught.value.detail


def test_non_finite_and_sentinel_positions_are_refused() -> None:
    sim = simulate_plane_touches(8, seed=6)
    f = sim.f.copy()
    f[3, 1] = -3.7e28
    with pytest.raises(InvalidInput) as caught:
        solve_plane(sim.R, f)
    assert caught.value.kind == "out-of-range"
    f[3, 1] = np.nan
    with pytest.raises(InvalidInput) as caught:
        solve_plane(sim.R, f)
    assert caught.value.kind == "non-finite"
