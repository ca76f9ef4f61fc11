"""XYZ reference method and TCP check, with propagated uncertainty."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.solvers.npoint import solve_npoint
from app.solvers.reference import check_tcp, reference_point_from_touch, solve_reference
from testbed.sim.touches import simulate_touches, touch_rotations

TOOL_A = np.array([12.0, -4.0, 180.0])
TOOL_B = np.array([-30.0, 8.0, 95.0])
POINT = np.array([650.0, 120.0, 310.0])


def _touch(rng: np.random.Generator, tcp: np.ndarray, noise: float) -> tuple[np.ndarray, ...]:
    R = touch_rotations(rng, 1, tilt_deg=30.0, spin=True).as_matrix()[0]
    f = POINT - R @ tcp + rng.normal(0.0, noise, 3)
    return R, f


def test_noise_free_reference_chain_is_exact() -> None:
    rng = np.random.default_rng(0)
    Ra, fa = _touch(rng, TOOL_A, 0.0)
    r, cov_r = reference_point_from_touch(
        tcp_mm=TOOL_A,
        tcp_covariance_mm2=np.zeros((3, 3)),
        rotation=Ra,
        position_mm=fa,
        touch_noise_mm=0.0,
    )
    assert_allclose(r, POINT, atol=1e-10)
    assert_allclose(cov_r, 0.0)
    Rb, fb = _touch(rng, TOOL_B, 0.0)
    result = solve_reference(
        reference_mm=r,
        reference_covariance_mm2=cov_r,
        rotation=Rb,
        position_mm=fb,
        touch_noise_mm=0.0,
    )
    assert_allclose(result.tcp_mm, TOOL_B, atol=1e-10)
    q = result.quality
    assert q.n_poses == 1
    assert q.residuals_mm == (0.0,)
    assert q.outliers == ()
    assert q.rms_mm == 0.0


def test_reference_point_covariance_is_rotated_tcp_covariance_plus_touch_noise() -> None:
    R = Rotation.from_euler("xyz", [170, 10, 40], degrees=True).as_matrix()
    cov_t = np.diag([0.01, 0.02, 0.05]) ** 2
    _, cov_r = reference_point_from_touch(
        tcp_mm=TOOL_A,
        tcp_covariance_mm2=cov_t,
        rotation=R,
        position_mm=[500, 0, 400],
        touch_noise_mm=0.03,
    )
    assert_allclose(cov_r, R @ cov_t @ R.T + 0.03**2 * np.eye(3), atol=1e-15)


def test_tool_b_from_tool_a_reference_matches_truth_within_propagated_sigma() -> None:
    """N-point for tool A, its reference touch, then one touch of tool B: Monte Carlo."""
    noise, hits, trials, maha = 0.05, 0, 200, []
    for seed in range(trials):
        sim = simulate_touches(8, seed=seed, tcp_mm=TOOL_A, pivot_mm=np.array([0.0, 600, 200]))
        a = solve_npoint(sim.R, sim.f, touch_noise_mm=noise)
        rng = np.random.default_rng(10_000 + seed)
        Ra, fa = _touch(rng, TOOL_A, noise)
        r, cov_r = reference_point_from_touch(
            tcp_mm=a.tcp_mm,
            tcp_covariance_mm2=a.quality.tcp_covariance_mm2,
            rotation=Ra,
            position_mm=fa,
            touch_noise_mm=noise,
        )
        Rb, fb = _touch(rng, TOOL_B, noise)
        b = solve_reference(
            reference_mm=r,
            reference_covariance_mm2=cov_r,
            rotation=Rb,
            position_mm=fb,
            touch_noise_mm=noise,
        )
        err = b.tcp_mm - TOOL_B
        d2 = float(err @ np.linalg.solve(np.array(b.quality.tcp_covariance_mm2), err))
        maha.append(d2)
        hits += d2 <= b.quality.ellipsoid95_scale**2
    assert 0.91 <= hits / trials <= 0.99
    assert 2.4 < float(np.mean(maha)) < 3.6
    # the chain is worse than a single touch: it carries tool A's uncertainty as well
    assert min(b.quality.tcp_sigma_mm) > noise


def test_unknown_touch_noise_is_warned() -> None:
    rng = np.random.default_rng(1)
    Rb, fb = _touch(rng, TOOL_B, 0.0)
    result = solve_reference(
        reference_mm=POINT,
        reference_covariance_mm2=None,
        rotation=Rb,
        position_mm=fb,
        touch_noise_mm=None,
    )
    assert_allclose(result.tcp_mm, TOOL_B, atol=1e-10)
    assert any("touch noise is unknown" in w for w in result.quality.warnings)
    assert any("taken as exact" in w for w in result.quality.warnings)
    assert result.quality.tcp_sigma_mm == (0.0, 0.0, 0.0)


def test_check_of_a_good_tool_is_zero_and_a_bent_tool_shows_its_bend() -> None:
    rng = np.random.default_rng(2)
    R, f = _touch(rng, TOOL_A, 0.0)
    good = check_tcp(tcp_mm=TOOL_A, rotation=R, position_mm=f, reference_mm=POINT)
    assert good.distance_mm == pytest.approx(0.0, abs=1e-10)
    bend = np.array([0.8, -0.3, 0.0])  # the real tip moved 0.8 / -0.3 mm in the flange frame
    f_bent = POINT - R @ (TOOL_A + bend)
    bent = check_tcp(tcp_mm=TOOL_A, rotation=R, position_mm=f_bent, reference_mm=POINT)
    assert_allclose(bent.deviation_flange_mm, bend, atol=1e-10)  # new minus old
    assert_allclose(bent.deviation_base_mm, R @ bend, atol=1e-10)
    assert bent.distance_mm == pytest.approx(np.linalg.norm(bend))


@pytest.mark.parametrize(
    ("kwargs", "kind"),
    [
        ({"position_mm": [0.0, 0.0, -3.7e28]}, "out-of-range"),
        ({"position_mm": [0.0, np.nan, 0.0]}, "non-finite"),
        ({"rotation": 1.02 * np.eye(3)}, "invalid-rotation"),
        ({"rotation": np.diag([1.0, 1.0, -1.0])}, "invalid-rotation"),
        ({"touch_noise_mm": -1.0}, "invalid-options"),
        (
            {"reference_covariance_mm2": [[1.0, 2.0, 0], [0, 1.0, 0], [0, 0, 1.0]]},
            "invalid-options",
        ),
        ({"reference_covariance_mm2": -np.eye(3)}, "invalid-options"),
        ({"reference_mm": [1.0, 2.0]}, "invalid-pose"),
    ],
)
def test_bad_inputs_are_refused(kwargs: dict[str, object], kind: str) -> None:
    args: dict[str, Any] = {
        "reference_mm": POINT,
        "reference_covariance_mm2": None,
        "rotation": np.eye(3),
        "position_mm": [600.0, 100.0, 150.0],
        "touch_noise_mm": 0.05,
    }
    args.update(kwargs)
    with pytest.raises(InvalidInput) as info:
        solve_reference(**args)
    assert info.value.kind == kind


def test_check_refuses_sentinel_positions() -> None:
    with pytest.raises(InvalidInput) as info:
        check_tcp(tcp_mm=TOOL_A, rotation=np.eye(3), position_mm=[-3.7e28] * 3, reference_mm=POINT)
    assert info.value.kind == "out-of-range"
