"""`tcpcal check-frame FRAME TOUCHES --pointer TOOL --format F [--correct] [--robot]` (issue
49): the frame's re-check after a move said in words, each verdict its exit code as `tcpcal
check` gives them (0 in tolerance, 1 corrected, 7 needs recalibration, 4 refused)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from app.cli import cli
from tests.api.frame_fiducials import calibrated_frame, cell, touches
from tests.cli.in_process import cli_as
from tests.conftest import Api

R, ORIGIN = np.eye(3), np.array([500.0, 0.0, 0.0])


@pytest.fixture
def runner(api: Api, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    return cli_as("calibrate", api, monkeypatch)


@pytest.mark.parametrize(
    ("moved_mm", "args", "code", "said"),
    [
        (0.0, [], 0, "within check_mm 0.5 mm: nothing to correct"),
        (1.5, ["--correct", "--reason", "unbolted"], 1, "corrected as version 2 (was 1)"),
        (1.5, [], 7, 'resend with "correct": "within_limits"'),
        (8.0, ["--correct"], 7, "beyond max_correction_mm 5 mm: nothing was changed"),
    ],
)
def test_each_verdict_is_said_and_exits_with_its_code(
    api: Api,
    runner: CliRunner,
    tmp_path: Path,
    moved_mm: float,
    args: list[str],
    code: int,
    said: str,
) -> None:
    robot, pointer = cell(api)
    frame = calibrated_frame(api, robot["id"], "fixture-a", R, ORIGIN, pointer_id=pointer["id"])
    body = touches(pointer["id"], R, ORIGIN + np.array([moved_mm, 0.0, 0.0]))
    path = tmp_path / "touches.json"
    path.write_text(json.dumps(body["touches"]))
    command = ["check-frame", "kr16/fixture-a", str(path), "--pointer", pointer["id"]]
    result = runner.invoke(cli, [*command, "--format", "matrix", *args])
    assert result.exit_code == code, result.output
    assert said in " ".join(result.output.split())
    assert "fiducial 'pin1' moved" in result.output
    versions = api.get(f"/v1/frames/{frame['id']}/versions").json()["items"]
    assert len(versions) == (2 if code == 1 else 1)


def test_a_touch_far_from_its_fiducial_is_refused_with_4(
    api: Api, runner: CliRunner, tmp_path: Path
) -> None:
    robot, pointer = cell(api)
    frame = calibrated_frame(api, robot["id"], "fixture-a", R, ORIGIN, pointer_id=pointer["id"])
    body = touches(pointer["id"], R, ORIGIN, names=["a", "b", "c"])
    body["touches"][1]["fiducial"], body["touches"][2]["fiducial"] = "c", "b"
    path = tmp_path / "touches.json"
    path.write_text(json.dumps(body["touches"]))
    result = runner.invoke(
        cli, ["check-frame", frame["id"], str(path), "--pointer", "pointer", "--format", "matrix"]
    )
    assert result.exit_code == 4, result.output
    assert "from fiducial 'b'" in " ".join(result.output.split())
