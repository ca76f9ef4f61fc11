"""Real pivot recordings of one NDI Polaris stylus (tests/data/ndi-pivot): same maths as N-point.

The marker body plays the flange, the camera the robot base. Two recordings of the same
stylus must give the same tip offset within their uncertainty. The stream is sampled at a
high rate and consecutive frames share their errors (lag-1 residual correlation ~0.95), so
the reported uncertainty, which assumes independent touches, is only honest on frames far
enough apart: the agreement checks use every 50th frame (correlation gone by then).
"""

from __future__ import annotations

import csv
from functools import cache

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.solvers.npoint import ALGORITHMS, NPointResult, solve_npoint
from app.words import Algorithm
from tests.realdata import NDI_PIVOT

DATA = NDI_PIVOT
FILES = ("pivot_2.csv", "pivot_3.csv")
STRIDE = 50


@cache
def load(name: str) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Rotations (N, 3, 3) marker->camera, positions (N, 3) mm and each row's State."""
    with (DATA / name).open(newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    assert header[4] == "State"
    assert header[5:12] == ["Q0", "Qx", "Qy", "Qz", "Tx", "Ty", "Tz"]
    body = rows[1:]
    quat = np.array([[float(x) for x in r[5:9]] for r in body])
    pos = np.array([[float(x) for x in r[9:12]] for r in body])
    states = tuple(r[4] for r in body)
    ok = np.array([s == "OK" for s in states])
    R = np.full((len(body), 3, 3), np.nan)
    R[ok] = Rotation.from_quat(quat[ok], scalar_first=True).as_matrix()
    return R, pos, states


def ok_rows(name: str) -> tuple[np.ndarray, np.ndarray]:
    R, pos, states = load(name)
    ok = np.array([s == "OK" for s in states])
    return R[ok], pos[ok]


@cache
def solved(name: str, algorithm: Algorithm, stride: int) -> NPointResult:
    R, f = ok_rows(name)
    return solve_npoint(R[::stride], f[::stride], algorithm=algorithm)


def test_every_frame_gives_sub_millimetre_residuals_and_flags_the_stream_correlation() -> None:
    for name in FILES:
        R, f = ok_rows(name)
        assert len(R) > 500
        result = solve_npoint(R, f)
        q = result.quality
        assert q.rms_mm < 0.5
        assert q.max_mm < 1.5
        assert q.orientation_spread_deg > 45.0
        assert 150.0 < np.linalg.norm(result.tcp_mm) < 165.0
        assert len(q.outliers) < 0.05 * len(R)
        assert any("correlated" in w for w in q.warnings)


def test_the_two_recordings_agree_within_their_combined_uncertainty() -> None:
    a, b = (solved(name, "robust", STRIDE) for name in FILES)
    diff = a.tcp_mm - b.tcp_mm
    combined = np.sqrt(np.square(a.quality.tcp_sigma_mm) + np.square(b.quality.tcp_sigma_mm))
    assert np.all(combined < 0.5)
    assert np.all(np.abs(diff) <= 3.0 * combined), (diff, combined)
    assert np.linalg.norm(diff) < 1.0
    for r in (a, b):
        assert r.quality.rms_mm < 0.5


@pytest.mark.parametrize("name", FILES)
def test_every_algorithm_agrees_within_the_uncertainty(name: str) -> None:
    ref = solved(name, "robust", STRIDE)
    sigma = np.array(ref.quality.tcp_sigma_mm)
    for algorithm in ALGORITHMS:
        if algorithm == "sphere":
            continue  # the biased baseline: checked separately below
        other = solved(name, algorithm, STRIDE)
        both = np.sqrt(sigma**2 + np.square(other.quality.tcp_sigma_mm))
        assert np.all(np.abs(other.tcp_mm - ref.tcp_mm) <= 3.0 * both), algorithm
    # the sphere fit is biased under noise, yet within its own (wide) uncertainty
    sphere = solved(name, "sphere", STRIDE)
    both = np.sqrt(sigma**2 + np.square(sphere.quality.tcp_sigma_mm))
    assert np.all(np.abs(sphere.tcp_mm - ref.tcp_mm) <= 3.0 * both)


def test_stacked_and_gls_coincide_without_orientation_noise() -> None:
    R, f = ok_rows("pivot_2.csv")
    stacked = solve_npoint(R, f, algorithm="stacked")
    gls = solve_npoint(R, f, algorithm="gls")
    assert_allclose(gls.tcp_mm, stacked.tcp_mm, atol=1e-9)


def test_a_lost_tool_row_is_refused_not_averaged() -> None:
    R, f = ok_rows("pivot_3.csv")
    R, f = R[:40:4].copy(), f[:40:4].copy()
    f[5] = [-3.7e28, -3.7e28, -3.7e28]  # what the tracker reports for a missing tool
    with pytest.raises(InvalidInput) as info:
        solve_npoint(R, f)
    assert info.value.kind == "out-of-range"
    assert info.value.loc == ("poses", 5, "position")


def test_a_lost_tool_rotation_is_refused() -> None:
    R, f = ok_rows("pivot_2.csv")
    R = R[:40:4].copy()
    R[2] = -3.7e28
    with pytest.raises(InvalidInput) as info:
        solve_npoint(R, f[:40:4])
    assert info.value.kind == "invalid-rotation"
