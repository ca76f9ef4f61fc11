"""app.kinematics.frames against 4x4 homogeneous matrices built here with numpy alone: the
flange a controller's TCP reading implies (base @ tcp @ inverse(tool))."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from app.kinematics.frames import compose, flange_from_tcp, inverse


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula, written out: no scipy, so the test does not share the code's path."""
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R: np.ndarray = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    return R


def _quaternion(R: np.ndarray) -> tuple[float, float, float, float]:
    """[w, x, y, z] of a rotation matrix (Shepperd's method, the branch on the largest)."""
    trace = np.trace(R)
    candidates = [trace, R[0, 0], R[1, 1], R[2, 2]]
    i = int(np.argmax(candidates))
    if i == 0:
        w = np.sqrt(1 + trace) / 2
        q = [
            w,
            (R[2, 1] - R[1, 2]) / (4 * w),
            (R[0, 2] - R[2, 0]) / (4 * w),
            (R[1, 0] - R[0, 1]) / (4 * w),
        ]
    else:
        j, k = (i % 3) + 1, ((i + 1) % 3) + 1
        a, b, c = i - 1, j - 1, k - 1
        s = np.sqrt(1 + R[a, a] - R[b, b] - R[c, c]) * 2
        q = [0.0] * 4
        q[0] = (R[c, b] - R[b, c]) / s
        q[i] = s / 4
        q[j] = (R[b, a] + R[a, b]) / s
        q[k] = (R[c, a] + R[a, c]) / s
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def _homogeneous(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _matrix(frame: tuple[tuple[float, ...], tuple[float, ...]]) -> np.ndarray:
    (x, y, z), (w, qx, qy, qz) = frame
    angle = 2 * np.arccos(np.clip(w, -1, 1))
    axis = np.array([qx, qy, qz]) if np.linalg.norm([qx, qy, qz]) > 1e-12 else np.array([1, 0, 0])
    return _homogeneous(_axis_angle(axis, angle), np.array([x, y, z]))


unit = st.floats(-1, 1, allow_nan=False)
frames = st.tuples(
    st.tuples(unit, unit, unit).filter(lambda v: np.linalg.norm(v) > 0.1),
    st.floats(-3.1, 3.1),
    st.tuples(*(st.floats(-2000, 2000),) * 3),
)


def _frame(
    spec: tuple[tuple[float, float, float], float, tuple[float, float, float]],
) -> tuple[np.ndarray, Any]:
    axis, angle, t = spec
    R = _axis_angle(np.array(axis), angle)
    return _homogeneous(R, np.array(t)), (tuple(t), _quaternion(R))


@settings(max_examples=60, deadline=None)
@given(frames, frames, frames)
def test_flange_is_base_times_tcp_times_inverse_tool(a: Any, b: Any, c: Any) -> None:
    base_T, base = _frame(a)
    tcp_T, tcp = _frame(b)
    tool_T, tool = _frame(c)
    expected = base_T @ tcp_T @ np.linalg.inv(tool_T)
    got = _matrix(flange_from_tcp(tcp, tool=tool, base=base))
    assert_allclose(got, expected, atol=1e-8)


@settings(max_examples=40, deadline=None)
@given(frames)
def test_inverse_composes_to_the_identity(a: Any) -> None:
    _, frame = _frame(a)
    position, quaternion = compose(frame, inverse(*frame))
    assert_allclose(position, [0, 0, 0], atol=1e-9)
    assert_allclose(abs(quaternion[0]), 1.0, atol=1e-12)


def test_a_known_flange() -> None:
    # The TCP 150 mm out along the flange's z, the flange turned 90 deg about the base's x:
    # the TCP at (100, -150, 500) puts the flange at (100, 0, 500).
    tool = ((0.0, 0.0, 150.0), (1.0, 0.0, 0.0, 0.0))
    half = np.sqrt(0.5)
    tcp = ((100.0, -150.0, 500.0), (half, half, 0.0, 0.0))
    position, quaternion = flange_from_tcp(tcp, tool=tool)
    assert_allclose(position, [100.0, 0.0, 500.0], atol=1e-9)
    assert_allclose(quaternion, [half, half, 0.0, 0.0], atol=1e-12)
    bare_position, bare_quaternion = flange_from_tcp(tcp)  # no tool, no base: the reading
    assert_allclose(bare_position, tcp[0], atol=1e-12)
    assert_allclose(bare_quaternion, tcp[1], atol=1e-12)
