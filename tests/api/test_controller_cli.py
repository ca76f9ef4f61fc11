"""`tcpcal deploy` and `tcpcal reconcile` against the app and a controller simulator: the
tables and the exit codes (0 verified / in sync, 2 drifted, 3 unreachable)."""

from __future__ import annotations

import httpx
import pytest
from typer.testing import CliRunner

from app import client_http
from app.cli import cli
from tests.api.controller_rigs import rig
from tests.api.test_deployments import ACTIVE_POSITION, ACTIVE_Q, _setup
from tests.conftest import Api


@pytest.fixture
def runner(api: Api, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    """The commands talk to the in-process app (its test transport) with a calibrate key."""

    def http() -> httpx.Client:
        return httpx.Client(
            transport=api.client._transport,
            base_url="http://testserver",
            headers=api.headers("calibrate"),
        )

    monkeypatch.setattr(client_http, "connect", http)
    monkeypatch.setenv("COLUMNS", "250")
    return CliRunner()


def test_deploy_and_reconcile_exit_codes(api: Api, runner: CliRunner) -> None:
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        tool_id, robot_id = ids["tool"]["id"], ids["robot"]["id"]
        done = runner.invoke(cli, ["deploy", tool_id])
        assert done.exit_code == 0, done.output
        assert "verified: $TOOL_DATA[3] holds version 1" in done.output
        synced = runner.invoke(cli, ["reconcile", robot_id])
        assert synced.exit_code == 0, synced.output
        assert "in_sync" in synced.output
        r.set_behind_back([ACTIVE_POSITION[0] + 1, *ACTIVE_POSITION[1:]], ACTIVE_Q)
        drifted = runner.invoke(cli, ["reconcile", robot_id])
        assert drifted.exit_code == 2, drifted.output
        assert f"drifted: {tool_id} at $TOOL_DATA[3] is off by 1.0000 mm" in drifted.output
        r.sim.stop()
        gone = runner.invoke(cli, ["reconcile", robot_id])
        assert gone.exit_code == 3, gone.output
        failed = runner.invoke(cli, ["deploy", tool_id])
        assert failed.exit_code == 3, failed.output
        assert "deployment" in failed.output


def test_help_says_the_exit_codes() -> None:
    for command in ("deploy", "reconcile"):
        shown = CliRunner().invoke(cli, [command, "--help"], env={"COLUMNS": "200"})
        assert "2 mismatch / drifted" in shown.output
        assert "3 controller unreachable" in shown.output
