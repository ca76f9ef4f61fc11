"""Each list is written once: the schema Literals equal the libraries' lists, and every
method-derived list equals the registry's."""

from __future__ import annotations

from typing import get_args

from app.api.methods import describe
from app.exports import CONTROLLER_FORMATS
from app.kinematics.poses import POSE_FORMATS
from app.methods import METHOD_NAMES, METHODS
from app.methods.npoint import Algorithm
from app.schemas.calibrations import SOLVE_MODELS, CalibrationRequest
from app.schemas.common import ControllerFormat, PoseFormat
from app.solvers.npoint import ALGORITHMS


def test_pose_formats_match_the_parser() -> None:
    assert get_args(PoseFormat) == tuple(POSE_FORMATS)


def test_controller_formats_match_the_exporters() -> None:
    assert get_args(ControllerFormat) == tuple(CONTROLLER_FORMATS)


def test_npoint_algorithms_match_the_solver() -> None:
    assert get_args(Algorithm) == ALGORITHMS


def test_the_request_unions_are_the_registry() -> None:
    union, _discriminator = get_args(CalibrationRequest)
    assert get_args(union) == tuple(m.request for m in METHODS)
    assert [m.__mro__[1] for m in SOLVE_MODELS] == [m.request for m in METHODS]
    assert [describe(m).name for m in METHODS] == list(METHOD_NAMES)
    assert len(set(METHOD_NAMES)) == len(METHODS) == 8
