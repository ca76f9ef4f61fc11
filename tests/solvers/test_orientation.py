"""Tool orientation: translations, KUKA 2-point touches, world alignment (METHODS section 4)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.solvers.orientation import (
    AxisDirection,
    Direction,
    OrientationResult,
    angle_between_deg,
    orientation_from_touches,
    orientation_from_translations,
    orientation_from_world,
    quaternion_wxyz_from_matrix,
    rotation_error_deg,
)
from app.words import WorkingAxis
from testbed.sim.frames import (
    random_rotation,
    tool_down,
    translation_directions,
    two_point_touches,
    world_aligned_rotation,
)

TCP = np.array([12.0, -7.5, 185.0])
Trial = Callable[[np.random.Generator], tuple[np.ndarray, OrientationResult]]


def _case(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return random_rotation(rng, 60.0), tool_down(rng, 35.0)


def _angle_deg(Q1: np.ndarray, Q2: np.ndarray) -> float:
    return float(np.degrees(Rotation.from_matrix(Q1.T @ Q2).magnitude()))


# ------------------------------------------------------------------ noise-free recovery


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize(
    "axes", [("+z", "+x"), ("-z", "-x"), ("+z", "-z", "+x"), ("+x", "-z", "-x")]
)
def test_translations_recover_the_frame(seed: int, axes: tuple[AxisDirection, ...]) -> None:
    Q, R = _case(seed)
    result = orientation_from_translations(translation_directions(Q, R, axes=axes))
    assert _angle_deg(result.rotation, Q) < 1e-9
    assert_allclose(result.residuals, 0.0, atol=1e-9)
    assert result.sigma_source == "none"
    q = np.array(result.quaternion_wxyz)
    assert q[0] >= 0
    assert_allclose(Rotation.from_quat(q, scalar_first=True).as_matrix(), Q, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_translations_z_only_take_x_from_the_flange(seed: int) -> None:
    Q, R = _case(seed)
    result = orientation_from_translations(translation_directions(Q, R, axes=("-z",)))
    assert_allclose(result.rotation[:, 2], Q[:, 2], atol=1e-12)
    x = np.array([1.0, 0.0, 0.0]) - Q[0, 2] * Q[:, 2]
    assert_allclose(result.rotation[:, 0], x / np.linalg.norm(x), atol=1e-12)
    assert any("no X move" in w for w in result.warnings)


def test_translations_allow_a_small_orientation_change() -> None:
    Q, R = _case(0)
    dirs = translation_directions(Q, R, axes=("+z", "+x"))
    tweak = Rotation.from_rotvec([0.0, 0.0, np.radians(0.3)]).as_matrix()
    d0 = dirs[0]
    dirs[0] = Direction(
        d0.axis, d0.rotation_from, d0.position_from_mm, R @ tweak, d0.position_to_mm
    )
    result = orientation_from_translations(dirs)
    # The mean of the two rotations is used: within half the change.
    assert _angle_deg(result.rotation, Q) < 0.3


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("working_axis", ["x", "z"])
def test_touches_recover_the_frame(seed: int, working_axis: WorkingAxis) -> None:
    Q, _ = _case(seed)
    rotations, positions = two_point_touches(
        Q, TCP, working_axis=working_axis, rng=np.random.default_rng(seed)
    )
    result = orientation_from_touches(
        tcp_mm=TCP,
        rotations=rotations,
        positions_mm=positions,
        working_axis=working_axis,
    )
    assert _angle_deg(result.rotation, Q) < 1e-9
    assert result.residuals == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize(
    "align",
    [
        {"x": "-z", "y": "+y"},
        {"z": "-z", "x": "+x"},
        {"y": "+x", "z": "-y"},
        {"x": "+y", "y": "-x", "z": "+z"},
        {"x": "z", "y": "x"},
    ],
)
def test_world_6d_recovers_the_frame(seed: int, align: dict[str, str]) -> None:
    Q, _ = _case(seed)
    R = world_aligned_rotation(Q, align)
    result = orientation_from_world(rotation=R, align=align)
    assert _angle_deg(result.rotation, Q) < 1e-9
    assert_allclose(result.rotation, R.T @ (R @ Q), atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("axis", ["x", "z"])
def test_world_5d_fixes_the_axis_and_stays_closest_to_the_flange(
    seed: int, axis: WorkingAxis
) -> None:
    Q, _ = _case(seed)
    align: dict[str, str] = {axis: "-z"}
    R = world_aligned_rotation(Q, align, spin_deg=37.0 * (seed + 1))
    result = orientation_from_world(rotation=R, align=align, working_axis=axis)
    a = "xyz".index(axis)
    assert_allclose(R @ result.rotation[:, a], [0.0, 0.0, -1.0], atol=1e-12)
    # No other twist about that axis is closer to the flange frame.
    best = np.degrees(Rotation.from_matrix(result.rotation).magnitude())
    e = np.zeros(3)
    e[a] = 1.0
    for phi in np.linspace(-np.pi, np.pi, 721):
        twisted = result.rotation @ Rotation.from_rotvec(phi * e).as_matrix()
        assert np.degrees(Rotation.from_matrix(twisted).magnitude()) >= best - 1e-9


def test_world_5d_half_turn_is_deterministic() -> None:
    R = np.diag([1.0, -1.0, -1.0])  # flange +Z down, flange +Y along base -y
    result = orientation_from_world(rotation=R, align={"z": "+z"}, working_axis="z")
    assert_allclose(R @ result.rotation[:, 2], [0.0, 0.0, 1.0], atol=1e-12)
    assert any("half-turn" in w for w in result.warnings)


def test_angle_between_matches_scipy() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = Rotation.random(2, random_state=rng)
        expected = np.degrees((a.inv() * b).magnitude())
        qa = quaternion_wxyz_from_matrix(a.as_matrix())
        qb = -np.array(quaternion_wxyz_from_matrix(b.as_matrix()))  # sign does not matter
        assert angle_between_deg(qa, qb) == pytest.approx(expected, abs=1e-9)


# ------------------------------------------------------------------ noise and uncertainty


def _normalised_errors(make: Trial, trials: int) -> np.ndarray:
    out = []
    for i in range(trials):
        Q, result = make(np.random.default_rng(1000 + i))
        err = rotation_error_deg(Q, result.rotation)
        out.append(err / np.array(result.sigma_deg))
    return np.array(out)


def _assert_calibrated(z: np.ndarray) -> None:
    std = z.std(axis=0)
    assert np.all((std > 0.85) & (std < 1.15)), std
    cover = (np.abs(z) < 1.96).mean(axis=0)
    assert np.all((cover > 0.90) & (cover < 0.99)), cover


def test_translation_sigma_matches_the_scatter() -> None:
    def make(rng: np.random.Generator) -> tuple[np.ndarray, OrientationResult]:
        Q, R = random_rotation(rng, 60.0), tool_down(rng, 35.0)
        dirs = translation_directions(
            Q, R, axes=("+z", "+x"), length_mm=40.0, noise_mm=0.05, rng=rng
        )
        return Q, orientation_from_translations(dirs, position_noise_mm=0.05)

    _assert_calibrated(_normalised_errors(make, 300))


def test_touch_sigma_matches_the_scatter() -> None:
    def make(rng: np.random.Generator) -> tuple[np.ndarray, OrientationResult]:
        Q = random_rotation(rng, 60.0)
        rotations, positions = two_point_touches(Q, TCP, noise_mm=0.1, rng=rng)
        result = orientation_from_touches(
            tcp_mm=TCP, rotations=rotations, positions_mm=positions, touch_noise_mm=0.1
        )
        return Q, result

    _assert_calibrated(_normalised_errors(make, 300))


def test_translation_sigma_scales_with_noise_over_length() -> None:
    Q, R = _case(1)
    a = orientation_from_translations(
        translation_directions(Q, R, length_mm=50.0), position_noise_mm=0.01
    )
    b = orientation_from_translations(
        translation_directions(Q, R, length_mm=100.0), position_noise_mm=0.04
    )
    assert_allclose(np.array(b.sigma_deg), 2.0 * np.array(a.sigma_deg), rtol=1e-4)
    # About tool x and y: the Z move alone: sqrt(2) sigma / L rad.
    assert a.sigma_deg[0] == pytest.approx(np.degrees(np.sqrt(2) * 0.01 / 50.0), rel=1e-4)


# ------------------------------------------------------------------ refusals


def test_refuses_orientation_change() -> None:
    Q, R = _case(0)
    dirs = translation_directions(Q, R)
    d = dirs[1]
    turned = R @ Rotation.from_euler("z", 0.8, degrees=True).as_matrix()
    dirs[1] = Direction(d.axis, d.rotation_from, d.position_from_mm, turned, d.position_to_mm)
    with pytest.raises(InvalidInput) as exc:
        orientation_from_translations(dirs)
    assert exc.value.kind == "orientation-changed"
    assert exc.value.loc == ("directions", 1, "to")
    assert "0.80 deg" in exc.value.detail


def test_refuses_short_translation() -> None:
    Q, R = _case(0)
    with pytest.raises(InvalidInput) as exc:
        orientation_from_translations(translation_directions(Q, R, length_mm=8.0))
    assert exc.value.kind == "invalid-direction"
    assert exc.value.loc == ("directions", 0, "to")


def test_refuses_x_parallel_to_z() -> None:
    Q, R = _case(0)
    z_move = translation_directions(Q, R, axes=("+z",))[0]
    x_wrong = Direction(
        "+x",
        z_move.rotation_from,
        z_move.position_from_mm,
        z_move.rotation_to,
        z_move.position_to_mm + R @ Q[:, 0] * 3.0,  # mostly along Z again
    )
    with pytest.raises(InvalidInput) as exc:
        orientation_from_translations([z_move, x_wrong])
    assert exc.value.kind == "invalid-direction"
    assert exc.value.loc == ("directions", 1, "to")


def test_refuses_missing_z() -> None:
    Q, R = _case(0)
    with pytest.raises(InvalidInput) as exc:
        orientation_from_translations(translation_directions(Q, R, axes=("+x",)))
    assert exc.value.kind == "invalid-direction"
    assert "Z" in exc.value.detail
    with pytest.raises(InvalidInput):
        orientation_from_translations([])


def test_refuses_contradicting_moves_on_one_axis() -> None:
    Q, R = _case(0)
    dirs = translation_directions(Q, R, axes=("+z", "+z"))
    d = dirs[1]
    dirs[1] = Direction("-z", d.rotation_from, d.position_from_mm, d.rotation_to, d.position_to_mm)
    with pytest.raises(InvalidInput) as exc:
        orientation_from_translations(dirs)
    assert exc.value.kind == "invalid-direction"


def test_refuses_bad_direction_rotation_and_nan() -> None:
    Q, R = _case(0)
    dirs = translation_directions(Q, R)
    d = dirs[0]
    dirs[0] = Direction(
        d.axis, d.rotation_from * 1.01, d.position_from_mm, d.rotation_to, d.position_to_mm
    )
    with pytest.raises(InvalidInput) as exc:
        orientation_from_translations(dirs)
    assert exc.value.kind == "invalid-rotation"
    assert exc.value.loc == ("directions", 0, "from")
    dirs = translation_directions(Q, R)
    d = dirs[1]
    dirs[1] = Direction(
        d.axis, d.rotation_from, d.position_from_mm, d.rotation_to, np.array([1.0, np.nan, 0])
    )
    with pytest.raises(InvalidInput) as exc:
        orientation_from_translations(dirs)
    assert exc.value.kind == "non-finite"


@pytest.mark.parametrize(
    ("align", "where"),
    [
        ({"x": "-z", "y": "+z"}, "y"),  # same base axis twice
        ({"x": "-z", "y": "-z"}, "y"),
        ({"x": "-w"}, "x"),  # not a base direction
        ({"q": "+z"}, "q"),  # not a tool axis
        ({"x": "+x", "y": "+y", "z": "-z"}, None),  # left-handed
        ({}, None),
    ],
)
def test_world_refuses_bad_alignments(align: dict[str, str], where: str | None) -> None:
    with pytest.raises(InvalidInput) as exc:
        orientation_from_world(rotation=np.eye(3), align=align)
    assert exc.value.kind == "invalid-options"
    assert exc.value.loc[:2] == ("options", "align")
    if where is not None:
        assert exc.value.loc[2] == where


def test_touches_refuse_collinear_points() -> None:
    Q, _ = _case(0)
    rotations, positions = two_point_touches(Q, TCP, lever_y_mm=0.0)
    with pytest.raises(InvalidInput) as exc:
        orientation_from_touches(tcp_mm=TCP, rotations=rotations, positions_mm=positions)
    assert exc.value.kind == "degenerate-poses"
    assert exc.value.loc == ("poses", 2)
    rotations, positions = two_point_touches(Q, TCP, lever_axis_mm=1.0)
    with pytest.raises(InvalidInput) as exc:
        orientation_from_touches(tcp_mm=TCP, rotations=rotations, positions_mm=positions)
    assert exc.value.kind == "degenerate-poses"
    assert exc.value.loc == ("poses", 1)


def test_touches_refuse_wrong_count_and_bad_options() -> None:
    Q, _ = _case(0)
    rotations, positions = two_point_touches(Q, TCP)
    with pytest.raises(InvalidInput) as exc:
        orientation_from_touches(tcp_mm=TCP, rotations=rotations[:2], positions_mm=positions[:2])
    assert exc.value.kind == "too-few-poses"
    with pytest.raises(InvalidInput) as exc:
        orientation_from_touches(
            tcp_mm=TCP,
            rotations=rotations,
            positions_mm=positions,
            working_axis="y",  # type: ignore[arg-type]  # deliberately not a WorkingAxis
        )
    assert exc.value.kind == "invalid-options"
    with pytest.raises(InvalidInput) as exc:
        orientation_from_touches(
            tcp_mm=TCP, rotations=rotations, positions_mm=positions, touch_noise_mm=-1.0
        )
    assert exc.value.kind == "invalid-options"
