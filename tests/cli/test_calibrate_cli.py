"""`tcpcal calibrate TOOL POSES_FILE` through typer's runner against the app: what it prints
is said as this CLI's commands, not as the HTTP calls the server names for an API client."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from app.cli import cli
from testbed.sim.touches import simulate_touches
from tests.api.capture_steps import POINT, TRUE_TCP
from tests.cli.test_controller_cli import runner as runner  # the app in process, calibrate key
from tests.cli.test_guided_cli import _kuka_abc, _tool
from tests.conftest import Api


def test_a_calibration_held_for_its_change_says_the_cli_command_that_activates_it(
    api: Api, runner: CliRunner, tmp_path: Path
) -> None:
    """The warning of a TCP that moved past max_change_mm named the HTTP call for an API
    client, its path a template ("POST /v1/tools/{tool_id}/versions/{version}/activate"):
    at the command line it says `tcpcal activate TOOL VERSION` (issue 51, defect 9)."""
    tool = _tool(api, None)
    api.manual(tool["id"], [0.0, 0.0, 150.0])  # version 1, active: 32 mm from the true TCP
    touches = simulate_touches(8, seed=21, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    poses = tmp_path / "touches.csv"
    poses.write_text(
        "\n".join(
            _kuka_abc(r, f).replace(" ", ",") for r, f in zip(touches.R, touches.f, strict=True)
        )
    )
    held = runner.invoke(cli, ["calibrate", "kr16/torch", str(poses), "--format", "kuka_abc"])
    assert held.exit_code == 0, held.output
    said = " ".join(held.output.split())
    assert "more than the tool's max_change_mm 5 mm: stored but not activated" in said
    assert "activate this version (tcpcal activate kr16/torch 2) or calibrate again with " in said
    assert "--activate always" in said
    assert "/v1/" not in said, said
    assert api.get(f"/v1/tools/{tool['id']}").json()["active_version"] == 1
