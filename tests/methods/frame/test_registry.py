"""The frame method registry: each entry's request, name and example, the union derived from
it, and the roles it declares against the constructions that use them."""

from __future__ import annotations

from typing import get_args

import numpy as np
import pytest

from app.errors import InvalidInput
from app.methods.frame import (
    FRAME_CALIBRATION_REQUESTS,
    FRAME_METHOD_NAMES,
    FRAME_METHODS,
    FrameCalibrationIn,
    frame_method_of,
)
from app.solvers.frame import Pointer
from app.words import FrameKind, FrameMethodName
from tests.methods.frame.given import GivenPointer


def test_the_union_is_the_registry_and_the_names_are_the_words() -> None:
    union, _discriminator = get_args(FrameCalibrationIn)
    members = get_args(union) or (union,)
    assert members == tuple(m.request for m in FRAME_METHODS)
    assert set(FRAME_METHOD_NAMES) <= set(get_args(FrameMethodName))


@pytest.mark.parametrize("method", FRAME_METHODS, ids=lambda m: m.name)
def test_each_example_solves(method) -> None:  # type: ignore[no-untyped-def]
    request = FRAME_CALIBRATION_REQUESTS.validate_python(method.example)
    assert frame_method_of(request) is method
    ctx = GivenPointer.of(Pointer.of([1.5, -2.0, 180.0], [0.02] * 3), kind=method.kinds[0])
    solved = method.solve(request, ctx)
    assert np.isclose(np.linalg.norm(solved.quaternion), 1.0)
    assert solved.summary


def test_a_method_refuses_a_frame_of_another_kind() -> None:
    wrong = [m for m in FRAME_METHODS if set(m.kinds) != {"base", "fixed_tool"}]
    for method in wrong:
        other: FrameKind = "base" if "base" not in method.kinds else "fixed_tool"
        request = FRAME_CALIBRATION_REQUESTS.validate_python(method.example)
        with pytest.raises(InvalidInput) as caught:
            method.solve(request, GivenPointer.of(Pointer.of([0, 0, 100]), kind=other))
        assert caught.value.kind == "unsupported"
        assert caught.value.loc == ("method",)
