"""A non-finite number in a solver's result is refused before anything is stored."""

from __future__ import annotations

import numpy as np
import pytest

from app.errors import InvalidInput
from app.methods.base import Solved
from app.schemas.results import QualityOut
from app.services.calibrations.contexts import StatelessContext
from app.services.calibrations.grading import graded_result


def test_nan_anywhere_in_the_result_is_a_422_kind() -> None:
    quality = QualityOut.ungraded(4).model_copy(
        update={"rms_mm": 0.1, "max_mm": 0.2, "tcp_sigma_mm": [0.1, np.nan, 0.1]}
    )
    solved = Solved(
        position_mm=np.array([0.0, 0.0, 100.0]),
        quaternion=None,
        algorithm="robust",
        quality=quality,
    )
    with pytest.raises(InvalidInput) as err:
        graded_result("xyz_npoint", solved, StatelessContext(None, None))
    assert err.value.kind == "non-finite"
    assert err.value.loc == ("quality", "tcp_sigma_mm", 1)


def test_finite_result_passes() -> None:
    solved = Solved(
        position_mm=np.array([0.0, 0.0, 100.0]),
        quaternion=None,
        quality=QualityOut.ungraded(0),
        graded=False,
    )
    result = graded_result("manual", solved, StatelessContext(None, None))
    assert result.tcp.position_mm == [0.0, 0.0, 100.0]
    assert result.tcp.quaternion == [1.0, 0.0, 0.0, 0.0]
