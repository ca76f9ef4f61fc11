"""A non-finite number in a solver's result is refused before anything is stored."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from app.methods.base import SolvedTcp, empty_quality
from app.services.calibrate import result_document
from app.services.contexts import StatelessContext
from app.solvers.errors import SolveError


def test_nan_anywhere_in_the_result_is_a_422_kind() -> None:
    quality = empty_quality(4) | {"rms_mm": 0.1, "max_mm": 0.2, "tcp_sigma_mm": [0.1, np.nan, 0.1]}
    solved = SolvedTcp(
        position_mm=np.array([0.0, 0.0, 100.0]), quaternion=None, algorithm="x", quality=quality
    )
    with pytest.raises(SolveError) as err:
        result_document(SimpleNamespace(method="xyz_npoint"), solved, StatelessContext(None, None))
    assert err.value.kind == "non-finite"
    assert err.value.loc == ("quality", "tcp_sigma_mm", 1)


def test_finite_result_passes() -> None:
    solved = SolvedTcp(
        position_mm=np.array([0.0, 0.0, 100.0]),
        quaternion=None,
        algorithm=None,
        quality=empty_quality(0),
        graded=False,
    )
    doc = result_document(SimpleNamespace(method="manual"), solved, StatelessContext(None, None))
    assert doc["tcp"] == {"position_mm": [0.0, 0.0, 100.0], "quaternion": [1.0, 0.0, 0.0, 0.0]}
