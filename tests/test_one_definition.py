"""Lists the schema layer must spell out as Literals stay equal to the libraries' own."""

from __future__ import annotations

from typing import get_args

from app.exports import CONTROLLER_FORMATS
from app.kinematics.poses import POSE_FORMATS
from app.methods import RUNNERS
from app.methods.catalog import CATALOG
from app.schemas.calibrations import METHOD_NAMES
from app.schemas.common import ControllerFormat, PoseFormat


def test_pose_formats_match_the_parser() -> None:
    assert get_args(PoseFormat) == tuple(POSE_FORMATS)


def test_controller_formats_match_the_exporters() -> None:
    assert get_args(ControllerFormat) == tuple(CONTROLLER_FORMATS)


def test_every_method_has_a_schema_a_runner_and_a_catalogue_entry() -> None:
    assert set(METHOD_NAMES) == set(RUNNERS) == set(CATALOG)
