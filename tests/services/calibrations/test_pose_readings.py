"""A solve reads a submission's poses once per reading (the method, then the mix-up check,
read the given one), and every reader gets arrays of its own."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from app.methods.requests import CALIBRATION_REQUESTS
from app.services.calibrations import contexts, grading
from app.services.calibrations.contexts import StatelessContext
from app.services.touches import tool_frames
from app.words import PoseFormat
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, str | None]]:
    """Every reading parsed from then on: (format, units)."""
    reads: list[tuple[str, str | None]] = []
    real = tool_frames.parse_poses_with

    def counted(kinematics: Any, fmt: PoseFormat, poses: Any, units: Any, **kwargs: Any) -> Any:
        reads.append((fmt, None if units is None else units.model_dump_json()))
        return real(kinematics, fmt, poses, units, **kwargs)

    monkeypatch.setattr(contexts, "parse_poses_with", counted)
    return reads


def test_a_good_submission_is_read_once(monkeypatch: pytest.MonkeyPatch) -> None:
    reads = _counting(monkeypatch)
    touches = simulate_touches(8, seed=4, tcp_mm=None)
    request = CALIBRATION_REQUESTS.validate_python(
        {"method": "xyz_npoint", "format": "kuka_abc", "poses": as_poses(touches, "kuka_abc")}
    )
    outcome = grading.solve(request, StatelessContext(None, None))
    assert outcome.result.status == "accepted"
    assert reads == [("kuka_abc", None)]


def test_a_mix_up_reads_each_reading_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """Sent in metres as if millimetres: refused, having tried each reading once."""
    from app.errors import InvalidInput

    reads = _counting(monkeypatch)
    touches = simulate_touches(8, seed=4, tcp_mm=None)
    poses = [[*(np.asarray(p[:3]) / 1000.0).tolist(), *p[3:]] for p in as_poses(touches)]
    request = CALIBRATION_REQUESTS.validate_python(
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": poses}
    )
    with pytest.raises(InvalidInput) as refused:
        grading.solve(request, StatelessContext(None, None))
    assert refused.value.kind == "convention-mismatch"
    assert reads[0] == ("xyz_wxyz", None)  # as given, then other readings
    assert len(reads) > 1
    assert len(reads) == len(set(reads)), reads


def test_each_reader_gets_arrays_of_its_own() -> None:
    touches = simulate_touches(5, seed=5, tcp_mm=None)
    poses = CALIBRATION_REQUESTS.validate_python(
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(touches)}
    ).poses
    assert poses is not None
    ctx = StatelessContext(None, None)
    rotations, positions = ctx.parse_poses("xyz_wxyz", poses, None, loc=("poses",))
    kept = positions.copy()
    rotations[:] = 0.0
    positions[:] = 0.0
    again_r, again_p = ctx.parse_poses("xyz_wxyz", poses, None, loc=("poses",))
    np.testing.assert_array_equal(again_p, kept)
    assert np.linalg.det(again_r).min() > 0.99
