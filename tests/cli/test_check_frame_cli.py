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
from app.cli import guided as client_guided
from testbed.sim.cell_frames import FIXTURE_MM, touch_frame
from tests.api.controller_rigs import rig
from tests.api.frame_fiducials import NAMES, POINTER_TCP, calibrated_frame, cell, touches
from tests.api.test_capture_controllers import SETUPS
from tests.api.test_capture_controllers import secret_key as secret_key  # autouse
from tests.api.test_frame_checks import O_FIXTURE, R_FIXTURE, _moved_in_frame, _on_controller
from tests.api.test_frame_recheck_sessions import ALONG
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


def test_captured_fiducials_of_a_moved_fixture_correct_it_with_1(
    api: Api, runner: CliRunner, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--capture: each fiducial the server names next read from the KUKA simulator on Enter
    (a recheck session), the fixture moved 1.5 mm / 0.3 deg corrected (exit 1)."""
    R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(ALONG), 0.3)
    moved = touch_frame(
        np.random.default_rng(49), FIXTURE_MM, frame=(R1, o1), tcp_mm=np.array(POINTER_TCP)
    )
    at = {
        n: (rot, pos)
        for n, rot, pos in zip(NAMES, moved.rotations, moved.positions_mm, strict=True)
    }
    prompts: list[str] = []
    with rig("kuka_kvp") as r:
        place = SETUPS["kuka_kvp"](r)
        _, pointer, frame = _on_controller(api, r)

        def operator(prompt: str) -> str | None:
            prompts.append(prompt)
            name = prompt.split("'")[1]
            place.place(*at[name])
            return "\n"

        monkeypatch.setattr(client_guided, "_read_line", operator)
        command = ["check-frame", frame["id"], "--capture", "--pointer", pointer["id"]]
        result = runner.invoke(
            cli, [*command, "--format", "kuka_abc", "--correct", "--reason", "unbolted"]
        )
    assert result.exit_code == 1, result.output
    assert [p.split("'")[1] for p in prompts] == NAMES
    assert "corrected as version 2 (was 1)" in " ".join(result.output.split())
    versions = api.get(f"/v1/frames/{frame['id']}/versions").json()["items"]
    assert len(versions) == 2
