"""`manual` for a frame: numbers or one pose, checked; nothing touched, nothing graded."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.spatial.transform import Rotation

from app.methods.frame import FRAME_CALIBRATION_REQUESTS, FRAME_METHODS_BY_NAME
from app.solvers.frame import Pointer
from testbed.sim.cell_frames import random_frame
from tests.methods.frame.bodies import angle_deg
from tests.methods.frame.given import GivenPointer

CTX = GivenPointer.of(Pointer.of([0.0, 0.0, 150.0]))


def _solve(body: dict[str, object]):  # type: ignore[no-untyped-def]
    request = FRAME_CALIBRATION_REQUESTS.validate_python({"method": "manual", **body})
    return FRAME_METHODS_BY_NAME["manual"].solve(request, CTX)


def test_numbers_are_the_frame_and_no_quaternion_is_the_base_axes() -> None:
    solved = _solve({"frame": {"position_mm": [100.0, -20.0, 5.0]}})
    assert solved.position_mm.tolist() == [100.0, -20.0, 5.0]
    assert solved.quaternion.tolist() == [1.0, 0.0, 0.0, 0.0]
    assert not solved.graded
    assert solved.tool is None
    assert solved.fiducials == []
    assert solved.quality.n_touches == 0
    assert solved.quality.position_sigma_mm is None


def test_one_pose_is_the_frame() -> None:
    q = Rotation.from_euler("ZYX", [30.0, -10.0, 5.0], degrees=True)
    x, y, z, w = q.as_quat()
    solved = _solve({"format": "xyz_wxyz", "poses": [[1.0, 2.0, 3.0, w, x, y, z]]})
    np.testing.assert_allclose(solved.position_mm, [1.0, 2.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(abs(solved.quaternion @ [w, x, y, z]), 1.0, atol=1e-12)


@pytest.mark.parametrize(
    "body",
    [
        {},
        {"frame": {"position_mm": [0, 0, 0]}, "format": "xyz_wxyz", "poses": [[0] * 7]},
        {"format": "xyz_wxyz"},
        {"frame": {"position_mm": [0, 0, 0]}, "tool_id": "pointer"},
    ],
)
def test_numbers_or_one_pose_and_no_pointer(body: dict[str, object]) -> None:
    with pytest.raises(ValidationError):
        FRAME_CALIBRATION_REQUESTS.validate_python({"method": "manual", **body})


def test_200_frames_entered_as_one_kuka_pose_to_1e_9() -> None:
    """A frame pasted as X Y Z A B C (the kuka_abc format) is the frame: 200 seeded frames."""
    rng = np.random.default_rng(47)
    for _ in range(200):
        R, o = random_frame(rng)
        a, b, c = Rotation.from_matrix(R).as_euler("ZYX", degrees=True)
        solved = _solve({"format": "kuka_abc", "poses": [[*map(float, o), a, b, c]]})
        assert np.abs(solved.position_mm - o).max() < 1e-9
        assert angle_deg(solved.quaternion, R) < 1e-9
