"""Quaternion <-> KUKA ABC / Fanuc WPR, the conversions the controller connectors use:
round trips (hypothesis) and known values written out by hand."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from app.kinematics.poses import (
    fanuc_wpr_from_quaternion_wxyz,
    kuka_abc_from_quaternion_wxyz,
    matrix_from_quaternion_wxyz,
    quaternion_wxyz_from_fanuc_wpr,
    quaternion_wxyz_from_kuka_abc,
    rotation_angle_deg,
)

FAST = settings(
    max_examples=200, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
quaternions = st.lists(
    st.floats(-1, 1, allow_nan=False, allow_infinity=False), min_size=4, max_size=4
).filter(lambda q: math.sqrt(sum(v * v for v in q)) > 0.1)
angles = st.tuples(st.floats(-179.9, 179.9), st.floats(-89.0, 89.0), st.floats(-179.9, 179.9))


def unit(q: list[float]) -> np.ndarray:
    v: np.ndarray = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return v if v[0] >= 0 else -v


@FAST
@given(quaternions)
def test_quaternion_kuka_abc_quaternion(q: list[float]) -> None:
    quaternion = unit(q)
    back = quaternion_wxyz_from_kuka_abc(kuka_abc_from_quaternion_wxyz(quaternion))
    assert rotation_angle_deg(quaternion, back) < 1e-6


@FAST
@given(quaternions)
def test_quaternion_fanuc_wpr_quaternion(q: list[float]) -> None:
    quaternion = unit(q)
    back = quaternion_wxyz_from_fanuc_wpr(fanuc_wpr_from_quaternion_wxyz(quaternion))
    assert rotation_angle_deg(quaternion, back) < 1e-6


@FAST
@given(angles)
def test_kuka_abc_away_from_gimbal_lock_round_trips_to_the_same_angles(
    abc: tuple[float, float, float],
) -> None:
    back = kuka_abc_from_quaternion_wxyz(quaternion_wxyz_from_kuka_abc(abc))
    assert_allclose(back, abc, atol=1e-6)


@FAST
@given(angles)
def test_fanuc_wpr_is_kuka_abc_listed_in_the_opposite_order(
    wpr: tuple[float, float, float],
) -> None:
    w, p, r = wpr
    assert (
        rotation_angle_deg(
            quaternion_wxyz_from_fanuc_wpr([w, p, r]), quaternion_wxyz_from_kuka_abc([r, p, w])
        )
        < 1e-6
    )


def test_known_values_written_out() -> None:
    # 90 deg about z: w = cos 45, z = sin 45; KUKA A = 90; Fanuc R = 90.
    q = [math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)]
    assert_allclose(kuka_abc_from_quaternion_wxyz(q), [90.0, 0.0, 0.0], atol=1e-9)
    assert_allclose(fanuc_wpr_from_quaternion_wxyz(q), [0.0, 0.0, 90.0], atol=1e-9)
    # Fanuc W = 90 (about x) maps y to z.
    m = matrix_from_quaternion_wxyz(quaternion_wxyz_from_fanuc_wpr([90.0, 0.0, 0.0]))
    assert_allclose(m @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], atol=1e-12)
    assert rotation_angle_deg([1, 0, 0, 0], [0, 1, 0, 0]) == 180.0
