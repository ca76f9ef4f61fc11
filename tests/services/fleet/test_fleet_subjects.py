"""The fleet and the plant's address space are written once for every subject
(app.services.subjects): their code names none (what differs is in the subjects'
declarations), and the tool's fleet reads as it did (its CSV's columns, its gauges' names)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from app.services.fleet.fleet import csv_columns, fleet_of
from app.services.fleet.gauges import declared_values
from app.services.subjects import IN_FLEET, SERVED, Served
from app.services.tools.subject import TOOL
from tests.services.lifecycle.test_subject import _code_words

APP = Path(__file__).resolve().parents[3] / "app"
GENERIC = [
    *sorted((APP / "services" / "fleet").glob("*.py")),
    *(APP / "publish" / name for name in ("opcua.py", "opcua_sink.py", "source.py", "sink.py")),
]
#: The words of the subjects declared (a tool's "tool", "tcp", a frame's "frame").
WORDS = {"tool", "tools", "tcp", "frame", "frames"}


@pytest.mark.parametrize("path", GENERIC, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_the_fleet_and_the_plant_tree_name_no_subject(path: Path) -> None:
    named = [w for w in _code_words(path) if WORDS & set(re.split(r"[^a-z]+", w.lower()))]
    assert named == []


def test_the_tool_fleet_csv_keeps_its_columns() -> None:
    (tool,) = [s for s in SERVED if s.subject is TOOL]
    assert csv_columns(tool) == (
        "tool_id", "tool", "slot", "robot", "cell", "active_version",
        "last_calibration_status", "last_calibration_rms_mm", "last_calibration_at",
        "last_check_within_tolerance", "last_check_distance_mm", "last_check_at", "attention",
        "active_x_mm", "active_y_mm", "active_z_mm",
        "active_qw", "active_qx", "active_qy", "active_qz",
        "controller_state", "controller_checked_at", "controller_deviation_mm",
        "controller_deviation_deg", "drift_rate_mm_per_month", "drift_sigma_mm_per_month",
        "drift_crosses_check_at", "live_state", "live_version", "live_checked_at",
    )  # fmt: skip


@pytest.mark.parametrize("served", IN_FLEET, ids=lambda s: s.subject.kind)
def test_each_subject_in_the_fleet_says_where_its_values_are(served: Served) -> None:
    """The plant's address space says what frame the values are given in."""
    assert served.value_in.startswith("the ")


@pytest.mark.parametrize("served", IN_FLEET, ids=lambda s: s.subject.kind)
def test_each_subjects_rules_are_the_codes_its_rows_declare(served: Served) -> None:
    """A rule whose code the row's schema does not declare would fail every row it holds
    for; a declared code may have no rule yet (a frame's checks and controller states,
    until its declaration has them), and the tool's every code has one."""
    row = fleet_of(served).side.row
    declared = declared_values(row, "attention")
    rules = tuple(fleet_of(served).rules)
    assert rules == tuple(code for code in declared if code in rules)
    if served.subject is TOOL:
        assert rules == declared
