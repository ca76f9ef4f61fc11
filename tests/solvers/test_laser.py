"""Laser-beam runout and offset (METHODS section 5) against the exact cylinder simulator."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.solvers.laser import LaserDevice, LaserResult, Sweep, solve_laser, teach_device
from testbed.sim.laser import (
    DEVICE,
    TOOL_STATES,
    CylinderTool,
    LaserData,
    make_tool,
    simulate,
    tool_down_rotation,
)

ROTATIONS = {
    "straight": tool_down_rotation(),
    "tilted": tool_down_rotation((0.7, -0.4), spin_deg=30.0),
    "rolled": tool_down_rotation((-1.5, 2.0), spin_deg=-115.0),
}


def _solve(data: LaserData, device: LaserDevice = DEVICE, **kw: Any) -> LaserResult:
    return solve_laser(
        flange_rotation=data.flange_rotation,
        sweeps=data.sweeps,
        descent_mm=data.descent_mm,
        device=device,
        **kw,
    )


def _assert_recovered(result: LaserResult, tool: CylinderTool, atol: float = 1e-9) -> None:
    assert_allclose(result.tcp_mm, tool.tcp_mm, atol=atol)
    assert_allclose(result.axis_direction_flange, tool.axis_direction, atol=atol)
    assert_allclose(result.axis_point_flange_mm, tool.axis_point_mm, atol=atol)
    assert result.tool_length_mm == pytest.approx(tool.length_mm, abs=atol)
    angle = np.degrees(Rotation.from_matrix(result.rotation.T @ tool.rotation).magnitude())
    assert angle < atol
    assert np.all(np.isfinite(result.residuals_mm))


# ------------------------------------------------------------------ the simulator itself


def _line_distance(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> float:
    n = np.cross(d1, d2)
    return float(abs((p2 - p1) @ n) / np.linalg.norm(n))


@pytest.mark.parametrize("state", list(TOOL_STATES))
@pytest.mark.parametrize("rot", list(ROTATIONS))
def test_simulated_triggers_are_tangent_to_the_cylinder(state: str, rot: str) -> None:
    """Independent of the simulator's closed form: at break and restore the beam line is
    exactly one radius from the tool axis (tangent to the infinite cylinder)."""
    tool = TOOL_STATES[state]
    R0 = ROTATIONS[rot]
    data = simulate(tool, flange_rotation=R0)
    beams = {
        "a": (np.array([0.0, DEVICE.beam_a_y_mm, DEVICE.plane_z_mm]), np.array([1.0, 0, 0])),
        "b": (np.array([DEVICE.beam_b_x_mm, 0.0, DEVICE.plane_z_mm]), np.array([0, 1.0, 0])),
    }
    for sweep in data.sweeps:
        for f in (sweep.break_mm, sweep.restore_mm):
            f = np.asarray(f)
            axis_point = f + R0 @ tool.axis_point_mm
            axis_dir = R0 @ tool.axis_direction
            d = _line_distance(axis_point, axis_dir, *beams[sweep.beam])
            assert d == pytest.approx(tool.radius_mm, abs=1e-12)
        # Between break and restore the beam cuts the tool: the midpoint is inside.
        mid = 0.5 * (np.asarray(sweep.break_mm) + np.asarray(sweep.restore_mm))
        d_mid = _line_distance(
            mid + R0 @ tool.axis_point_mm, R0 @ tool.axis_direction, *beams[sweep.beam]
        )
        assert d_mid == pytest.approx(0.0, abs=1e-9)
    tip = data.descent_mm + R0 @ tool.tcp_mm
    assert_allclose(tip, [DEVICE.beam_b_x_mm, DEVICE.beam_a_y_mm, DEVICE.plane_z_mm], atol=1e-12)


def test_runout_tool_is_built_with_the_papers_euler_convention() -> None:
    tool = TOOL_STATES["runout"]
    u = tool.axis_direction
    # u = Rx(tx) Ry(ty) z_hat, and METHODS' inverse ty = asin(u_x), tx = atan2(-u_y, u_z).
    assert np.degrees(np.arcsin(u[0])) == pytest.approx(-0.7, abs=1e-12)
    assert np.degrees(np.arctan2(-u[1], u[2])) == pytest.approx(1.2, abs=1e-12)


# ------------------------------------------------------------------ noise-free recovery


@pytest.mark.parametrize("state", list(TOOL_STATES))
@pytest.mark.parametrize("rot", list(ROTATIONS))
@pytest.mark.parametrize("heights", [(200.0, 240.0), (200.0, 220.0, 240.0)])
def test_every_tool_state_is_recovered_exactly(
    state: str, rot: str, heights: tuple[float, ...]
) -> None:
    tool = TOOL_STATES[state]
    result = _solve(simulate(tool, flange_rotation=ROTATIONS[rot], heights_mm=heights))
    _assert_recovered(result, tool)
    assert_allclose(result.offset_mm, tool.axis_point_mm[:2], atol=1e-9)
    assert len(result.heights_mm) == len(heights)
    assert_allclose(result.residuals_mm, 0.0, atol=1e-9)
    # Runout by scipy's Euler convention: u = Rx(tx) Ry(ty) z_hat.
    u = Rotation.from_euler("XY", result.runout_deg, degrees=True).apply([0.0, 0.0, 1.0])
    assert_allclose(u, tool.axis_direction, atol=1e-12)
    q = Rotation.from_quat(result.quaternion_wxyz, scalar_first=True)
    assert_allclose(q.as_matrix(), result.rotation, atol=1e-12)


@pytest.mark.parametrize("state", list(TOOL_STATES))
def test_runout_and_offset_match_the_tool_state(state: str) -> None:
    tool = TOOL_STATES[state]
    result = _solve(simulate(tool))
    expected_runout = {
        "ideal": (0.0, 0.0),
        "offset": (0.0, 0.0),
        "runout": (1.2, -0.7),
        "offset_runout": (-0.9, 1.5),
    }[state]
    assert_allclose(result.runout_deg, expected_runout, atol=1e-9)
    # Widths: 2 r sqrt(1 + (u.e/u_z)^2), a circle's diameter for an ideal tool.
    if state in ("ideal", "offset"):
        assert_allclose(result.widths_mm, 2 * tool.radius_mm, atol=1e-12)
    else:
        assert all(w > 2 * tool.radius_mm for w in result.widths_mm)


def test_return_sweeps_are_averaged() -> None:
    tool = TOOL_STATES["offset_runout"]
    result = _solve(simulate(tool, flange_rotation=ROTATIONS["tilted"], return_sweeps=True))
    _assert_recovered(result, tool)
    assert len(result.widths_mm) == 12


def test_sweeps_in_any_order_are_grouped_by_height() -> None:
    tool = TOOL_STATES["runout"]
    data = simulate(tool, heights_mm=(200.0, 215.0, 230.0, 240.0))
    rng = np.random.default_rng(5)
    shuffled = [data.sweeps[i] for i in rng.permutation(len(data.sweeps))]
    # Controller jitter in z well inside the grouping tolerance.
    jittered = [
        Sweep(
            s.beam,
            np.asarray(s.break_mm) + np.array([0, 0, 0.1]),
            np.asarray(s.restore_mm) + np.array([0, 0, 0.1]),
        )
        if i % 2
        else s
        for i, s in enumerate(shuffled)
    ]
    result = _solve(dataclasses.replace(data, sweeps=shuffled))
    _assert_recovered(result, tool)
    assert len(_solve(dataclasses.replace(data, sweeps=jittered)).heights_mm) == 4


@pytest.mark.parametrize("state", list(TOOL_STATES))
def test_teach_then_solve_round_trip(state: str) -> None:
    R0 = ROTATIONS["tilted"]
    ideal = TOOL_STATES["ideal"]
    taught = simulate(ideal, flange_rotation=R0)
    for axis in (None, ideal.axis_direction):
        device, fit = teach_device(
            flange_rotation=R0,
            sweeps=taught.sweeps,
            descent_mm=taught.descent_mm,
            tcp_mm=ideal.tcp_mm,
            tool_axis_flange=axis,
        )
        assert device.beam_a_y_mm == pytest.approx(DEVICE.beam_a_y_mm, abs=1e-9)
        assert device.beam_b_x_mm == pytest.approx(DEVICE.beam_b_x_mm, abs=1e-9)
        assert device.plane_z_mm == pytest.approx(DEVICE.plane_z_mm, abs=1e-9)
        assert_allclose(fit.residuals_mm, 0.0, atol=1e-9)
    tool = TOOL_STATES[state]
    _assert_recovered(_solve(simulate(tool, flange_rotation=R0), device=device), tool)


# ------------------------------------------------------------------ noise and uncertainty


def _errors(tool: CylinderTool, result: LaserResult) -> tuple[np.ndarray, np.ndarray]:
    u = tool.axis_direction
    true_runout = (np.degrees(np.arctan2(-u[1], u[2])), np.degrees(np.arcsin(u[0])))
    err = np.concatenate(
        [
            result.tcp_mm - tool.tcp_mm,
            np.array(result.runout_deg) - true_runout,
            np.array(result.offset_mm) - tool.axis_point_mm[:2],
            [result.tool_length_mm - tool.length_mm],
        ]
    )
    s = result.sigma
    sig = np.array([*s.tcp_mm, *s.runout_deg, *s.offset_mm, s.tool_length_mm])
    return err, sig


def test_reported_sigma_matches_the_scatter() -> None:
    tool = TOOL_STATES["offset_runout"]
    rng = np.random.default_rng(42)
    z = []
    for _ in range(200):
        data = simulate(tool, flange_rotation=ROTATIONS["tilted"], noise_mm=0.02, rng=rng)
        result = _solve(data, trigger_noise_mm=0.02)
        assert result.sigma.source == "configured"
        err, sig = _errors(tool, result)
        z.append(err / sig)
    z_arr = np.array(z)
    std = z_arr.std(axis=0)
    assert np.all((std > 0.85) & (std < 1.15)), std
    cover = (np.abs(z_arr) < 1.96).mean(axis=0)
    assert np.all((cover > 0.90) & (cover < 0.99)), cover


def test_sigma_from_residuals_with_three_or_more_heights() -> None:
    tool = TOOL_STATES["runout"]
    rng = np.random.default_rng(7)
    noise = []
    for _ in range(100):
        data = simulate(
            tool, heights_mm=(200.0, 210.0, 220.0, 230.0, 240.0), noise_mm=0.01, rng=rng
        )
        result = _solve(data)
        assert result.sigma.source == "residuals"
        noise.append(result.sigma.trigger_noise_mm)
    # The residual estimate of the trigger noise is unbiased in variance.
    assert np.sqrt(np.mean(np.square(noise))) == pytest.approx(0.01, rel=0.12)


def test_estimated_sigma_from_three_heights_still_covers_95_percent() -> None:
    """Three heights leave 2 degrees of freedom: the sigma is widened (Student's t) so that
    +-1.96 sigma holds the truth 95 % of the time, as with a given noise figure."""
    tool = TOOL_STATES["offset_runout"]
    rng = np.random.default_rng(5)
    z = []
    for _ in range(300):
        data = simulate(tool, flange_rotation=ROTATIONS["tilted"], noise_mm=0.02, rng=rng)
        result = _solve(data)
        assert result.sigma.source == "residuals"
        err, sig = _errors(tool, result)
        z.append(err / sig)
    cover = (np.abs(np.array(z)) < 1.96).mean(axis=0)
    assert np.all((cover > 0.92) & (cover < 0.985)), cover


def test_two_heights_without_noise_say_so() -> None:
    result = _solve(simulate(TOOL_STATES["ideal"], heights_mm=(200.0, 240.0)))
    assert result.sigma.source == "none"
    assert any("not estimated" in w for w in result.warnings)


def test_taught_device_sigma_matches_the_scatter() -> None:
    ideal = TOOL_STATES["ideal"]
    rng = np.random.default_rng(11)
    z = []
    for _ in range(150):
        data = simulate(ideal, noise_mm=0.02, rng=rng)
        device, fit = teach_device(
            flange_rotation=data.flange_rotation,
            sweeps=data.sweeps,
            descent_mm=data.descent_mm,
            tcp_mm=ideal.tcp_mm,
            trigger_noise_mm=0.02,
        )
        err = np.array(
            [
                device.beam_a_y_mm - DEVICE.beam_a_y_mm,
                device.beam_b_x_mm - DEVICE.beam_b_x_mm,
                device.plane_z_mm - DEVICE.plane_z_mm,
            ]
        )
        z.append(err / np.array(fit.sigma_mm))
    std = np.array(z).std(axis=0)
    assert np.all((std > 0.85) & (std < 1.15)), std


@pytest.mark.parametrize("axis_given", [True, False])
def test_taught_device_sigma_from_estimated_noise_covers_95_percent(axis_given: bool) -> None:
    """Three heights leave 4 (axis given) or 2 degrees of freedom: Student's t widening."""
    ideal = TOOL_STATES["ideal"]
    rng = np.random.default_rng(13)
    z = []
    for _ in range(300):
        data = simulate(ideal, noise_mm=0.02, rng=rng)
        device, fit = teach_device(
            flange_rotation=data.flange_rotation,
            sweeps=data.sweeps,
            descent_mm=data.descent_mm,
            tcp_mm=ideal.tcp_mm,
            tool_axis_flange=ideal.axis_direction if axis_given else None,
        )
        assert fit.sigma_source == "residuals"
        err = np.array(
            [
                device.beam_a_y_mm - DEVICE.beam_a_y_mm,
                device.beam_b_x_mm - DEVICE.beam_b_x_mm,
                device.plane_z_mm - DEVICE.plane_z_mm,
            ]
        )
        z.append(err / np.array(fit.sigma_mm))
    cover = (np.abs(np.array(z)) < 1.96).mean(axis=0)
    assert np.all((cover > 0.92) & (cover < 0.985)), cover


# ------------------------------------------------------------------ refusals


def _data(**kw: Any) -> LaserData:
    return simulate(TOOL_STATES["offset_runout"], **kw)


def _with_sweep(data: LaserData, i: int, sweep: Sweep) -> LaserData:
    sweeps = list(data.sweeps)
    sweeps[i] = sweep
    return dataclasses.replace(data, sweeps=sweeps)


def _refused(data: LaserData, kind: str, device: LaserDevice = DEVICE) -> InvalidInput:
    with pytest.raises(InvalidInput) as exc:
        _solve(data, device=device)
    assert exc.value.kind == kind, exc.value
    assert exc.value.detail
    return exc.value


def test_refuses_a_sweep_without_restore() -> None:
    data = _data()
    s = data.sweeps[3]
    err = _refused(_with_sweep(data, 3, Sweep(s.beam, s.break_mm, None)), "invalid-sweep")
    assert err.loc == ("sweeps", 3, "restore_mm")
    err = _refused(_with_sweep(data, 1, Sweep(s.beam, None, s.restore_mm)), "invalid-sweep")
    assert err.loc == ("sweeps", 1, "break_mm")


def test_refuses_break_equal_to_restore() -> None:
    data = _data()
    s = data.sweeps[2]
    err = _refused(_with_sweep(data, 2, Sweep(s.beam, s.break_mm, s.break_mm)), "invalid-sweep")
    assert err.loc == ("sweeps", 2, "restore_mm")


def test_refuses_a_sweep_along_the_wrong_axis() -> None:
    data = _data()
    s = data.sweeps[0]  # beam A: crossed moving along base Y
    b = np.asarray(s.break_mm)
    wrong = Sweep("a", b, b + np.array([6.0, 0.5, 0.0]))
    err = _refused(_with_sweep(data, 0, wrong), "invalid-sweep")
    assert err.loc == ("sweeps", 0, "restore_mm")
    assert "base X" in err.detail


def test_refuses_a_sweep_that_changes_height() -> None:
    data = _data()
    s = data.sweeps[1]
    climbing = Sweep(s.beam, s.break_mm, np.asarray(s.restore_mm) + np.array([0, 0, 2.0]))
    _refused(_with_sweep(data, 1, climbing), "invalid-sweep")


def test_refuses_a_single_height() -> None:
    err = _refused(_data(heights_mm=(220.0,)), "too-few-poses")
    assert err.loc == ("sweeps",)


def test_refuses_no_sweeps() -> None:
    err = _refused(dataclasses.replace(_data(), sweeps=[]), "too-few-poses")
    assert err.loc == ("sweeps",)


def test_refuses_an_axis_nearly_in_the_flange_plane() -> None:
    """Midpoints drifting 100 mm per 20 mm of height: no tool points that way."""
    data = _data(heights_mm=(200.0, 220.0))
    sweeps = [
        Sweep(
            s.beam,
            np.asarray(s.break_mm) + i // 2 * np.array([100.0, 100.0, 0.0]),
            np.asarray(s.restore_mm) + i // 2 * np.array([100.0, 100.0, 0.0]),
        )
        for i, s in enumerate(data.sweeps)
    ]
    _refused(dataclasses.replace(data, sweeps=sweeps), "degenerate-poses")


def test_refuses_heights_too_close() -> None:
    err = _refused(_data(heights_mm=(200.0, 203.0)), "invalid-sweep")
    assert err.loc == ("sweeps", 2, "break_mm")


def test_refuses_a_height_missing_a_beam() -> None:
    data = _data()
    sweeps = [s for i, s in enumerate(data.sweeps) if i != 3]  # height 2 loses beam B
    err = _refused(dataclasses.replace(data, sweeps=sweeps), "invalid-sweep")
    assert "beam B" in err.detail


def test_refuses_an_axis_point_off_the_tool() -> None:
    """A midpoint that puts the axis off the line by more than the tool's half-width."""
    data = _data()
    s = data.sweeps[2]
    shifted = Sweep(
        s.beam,
        np.asarray(s.break_mm) + np.array([0, 9.0, 0]),
        np.asarray(s.restore_mm) + np.array([0, 9.0, 0]),
    )
    err = _refused(_with_sweep(data, 2, shifted), "invalid-sweep")
    assert err.loc == ("sweeps", 2, "break_mm")


def test_refuses_a_descent_that_ends_above_the_swept_tool() -> None:
    data = _data()
    err = _refused(
        dataclasses.replace(data, descent_mm=data.descent_mm - np.array([0, 0, 60.0])),
        "invalid-sweep",
    )
    assert err.loc == ("descent_mm",)


def test_refuses_a_descent_away_from_the_beams() -> None:
    data = _data()
    err = _refused(
        dataclasses.replace(data, descent_mm=data.descent_mm + np.array([25.0, 25.0, 0])),
        "invalid-sweep",
    )
    assert err.loc == ("descent_mm",)


def test_refuses_a_device_above_the_flange() -> None:
    device = LaserDevice(DEVICE.beam_a_y_mm, DEVICE.beam_b_x_mm, plane_z_mm=230.0)
    _refused(_data(), "invalid-sweep", device=device)


def test_refuses_a_flange_not_pointing_down() -> None:
    data = _data()
    sideways = Rotation.from_euler("y", 90.0, degrees=True).as_matrix()
    err = _refused(dataclasses.replace(data, flange_rotation=sideways), "degenerate-poses")
    assert err.loc == ("poses", 0, "rotation")


def test_refuses_non_finite_and_bad_rotation() -> None:
    data = _data()
    s = data.sweeps[0]
    err = _refused(_with_sweep(data, 0, Sweep(s.beam, [np.nan, 0, 0], s.restore_mm)), "non-finite")
    assert err.loc[:3] == ("sweeps", 0, "break_mm")
    _refused(
        dataclasses.replace(data, flange_rotation=data.flange_rotation * 1.1), "invalid-rotation"
    )
    with pytest.raises(InvalidInput) as exc:
        _solve(data, trigger_noise_mm=-0.1)
    assert exc.value.kind == "invalid-options"


def test_never_a_nan_on_scrambled_input() -> None:
    """Randomly corrupted recordings either solve to finite numbers or are refused."""
    rng = np.random.default_rng(99)
    base = _data()
    solved = 0
    for _ in range(300):
        scale = rng.choice([0.0, 0.01, 0.3, 20.0])
        sweeps = []
        for s in base.sweeps:
            b = np.asarray(s.break_mm) + rng.normal(0, scale, 3)
            r = np.asarray(s.restore_mm) + rng.normal(0, scale, 3)
            beam = s.beam if rng.random() > 0.02 else ("a" if s.beam == "b" else "b")
            sweeps.append(Sweep(beam, b, r))
        descent = base.descent_mm + rng.normal(0, rng.choice([0.0, 0.3, 50.0]), 3)
        data = dataclasses.replace(base, sweeps=sweeps, descent_mm=descent)
        try:
            result = _solve(data, trigger_noise_mm=0.01)
        except InvalidInput:
            continue
        solved += 1
        values = np.concatenate(
            [result.tcp_mm, result.rotation.ravel(), result.residuals_mm, result.sigma.tcp_mm]
        )
        assert np.all(np.isfinite(values))
    assert 30 < solved < 300


def test_teach_refuses_like_solve() -> None:
    data = _data(heights_mm=(220.0,))
    with pytest.raises(InvalidInput) as exc:
        teach_device(
            flange_rotation=data.flange_rotation,
            sweeps=data.sweeps,
            descent_mm=data.descent_mm,
            tcp_mm=[0, 0, 150.0],
        )
    assert exc.value.kind == "too-few-poses"
    data = _data()
    with pytest.raises(InvalidInput) as exc:
        teach_device(
            flange_rotation=data.flange_rotation,
            sweeps=data.sweeps,
            descent_mm=data.descent_mm,
            tcp_mm=[0, 0, 150.0],
            tool_axis_flange=[0, 0, 0],
        )
    assert exc.value.kind == "invalid-options"


def test_make_tool_defaults_are_the_ideal_tool() -> None:
    assert_allclose(make_tool().tcp_mm, [0.0, 0.0, 150.0])
