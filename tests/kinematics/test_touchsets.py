"""Cone orientations: tilt is the angle between tool axes, spin turns about the tool axis, and
the flange positions put the TCP exactly on the point."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from app.kinematics.touchsets import cone_rotations, flange_positions, random_cone_rotations

angles = st.floats(min_value=0.0, max_value=80.0)
azimuths = st.floats(min_value=-360.0, max_value=360.0)
spins = st.floats(min_value=-180.0, max_value=180.0)
quats = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.1)


@settings(max_examples=200, deadline=None)
@given(quats, angles, azimuths, spins)
def test_tilt_is_the_angle_between_tool_axes_and_spin_keeps_the_axis(
    q: list[float], tilt: float, azimuth: float, spin: float
) -> None:
    start = Rotation.from_quat(q)
    r = cone_rotations(start, [tilt], [azimuth], [spin])
    z0 = start.apply([0.0, 0.0, 1.0])
    z = r.apply([0.0, 0.0, 1.0])[0]
    assert np.isclose(np.degrees(np.arccos(np.clip(z0 @ z, -1, 1))), tilt, atol=1e-5)
    unspun = cone_rotations(start, [tilt], [azimuth], [0.0])
    relative = (unspun.inv() * r)[0]  # a pure turn about the flange z axis by `spin`
    expected = Rotation.from_euler("z", spin, degrees=True)
    assert (relative * expected.inv()).magnitude() < 1e-9


@settings(max_examples=100, deadline=None)
@given(quats, st.lists(st.floats(-300, 300), min_size=3, max_size=3))
def test_flange_positions_put_the_tcp_on_the_point(q: list[float], tcp: list[float]) -> None:
    rng = np.random.default_rng(0)
    rotations = random_cone_rotations(
        rng, 6, Rotation.from_quat(q), max_tilt_deg=40.0, max_spin_deg=90.0
    )
    point = np.array([800.0, -120.0, 300.0])
    flanges = flange_positions(rotations, tcp, point)
    tips = flanges + rotations.apply(np.asarray(tcp))
    assert np.allclose(tips, point, atol=1e-9)


def test_random_cone_stays_within_its_limits() -> None:
    rng = np.random.default_rng(7)
    start = Rotation.from_euler("x", 180.0, degrees=True)
    rotations = random_cone_rotations(rng, 2000, start, max_tilt_deg=40.0, max_spin_deg=90.0)
    z = rotations.apply([0.0, 0.0, 1.0])
    tilt = np.degrees(np.arccos(np.clip(z @ start.apply([0.0, 0.0, 1.0]), -1, 1)))
    assert tilt.max() <= 40.0 + 1e-9
    assert tilt.max() > 38.0  # the whole cap is used
    # Uniform over the cap: half of its area lies below the angle whose 1 - cos is half.
    median = np.degrees(np.arccos(1 - (1 - np.cos(np.radians(40.0))) / 2))
    assert abs(np.mean(tilt < median) - 0.5) < 0.04
