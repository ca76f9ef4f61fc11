"""`tcpcal deploy` and `tcpcal reconcile` against the app and a controller simulator: the
tables and the exit codes (0 verified / in sync, 8 mismatch / drifted, 3 unreachable; 2 is
typer's bad use, never an outcome)."""

from __future__ import annotations

import re

import pytest
from typer.testing import CliRunner

from app.cli import cli
from app.cli import http as client_http
from app.cli.controllers import EXIT_CONTROLLER_UNREACHABLE, EXIT_DRIFTED
from app.cli.http import EXIT_BAD_USE, EXIT_NOT_FOUND, EXIT_REFUSED, EXIT_UNREACHABLE
from tests.api.controller_rigs import SLOT, rig
from tests.api.test_deployments import ACTIVE_POSITION, ACTIVE_Q, WRITE_REQUEST, _setup
from tests.api.test_deployments import secret_key as secret_key  # ABB's password, autouse
from tests.cli.in_process import cli_as
from tests.conftest import Api
from tests.controllers.simbase import go_silent


@pytest.fixture
def runner(api: Api, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    """The commands talk to the in-process app (its test transport) with a calibrate key."""

    return cli_as("calibrate", api, monkeypatch)


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
        assert drifted.exit_code == EXIT_DRIFTED == 8, drifted.output
        assert "drifted: t1 at $TOOL_DATA[3]" in drifted.output
        assert "off by      1.0000 mm, 0.0000 deg" in drifted.output
        r.sim.stop()
        gone = runner.invoke(cli, ["reconcile", robot_id])
        assert gone.exit_code == 3, gone.output
        failed = runner.invoke(cli, ["deploy", tool_id])
        assert failed.exit_code == 3, failed.output
        assert "deployment" in failed.output


@pytest.fixture
def narrow(monkeypatch: pytest.MonkeyPatch) -> None:
    """The client's consoles 80 columns wide, a cell PC's terminal."""
    from rich.console import Console

    from app.cli import client
    from app.cli import controllers as client_controllers

    for module in (client_http, client, client_controllers):
        monkeypatch.setattr(module, "out", Console(width=80))


@pytest.mark.parametrize("protocol", ["kuka_kvp", "abb_rws2"])
def test_deploy_and_reconcile_name_the_tool_and_show_the_whole_target_at_80_columns(
    api: Api, runner: CliRunner, narrow: None, protocol: str
) -> None:
    with rig(protocol) as r:
        ids = _setup(api, r, name="torch")
        robot = ids["robot"]
        target = "$TOOL_DATA[3]" if protocol == "kuka_kvp" else "T_ROB1/user/tTorch"
        done = runner.invoke(cli, ["deploy", f"{robot['name']}/torch"])
        assert done.exit_code == 0, done.output
        # the id is the database's (PostgreSQL's sequence runs on across tests)
        assert re.search(r"^deployment \d+ of torch: verified$", done.output, re.MULTILINE)
        assert f"  target     {target}\n" in done.output
        assert "…" not in done.output
        assert f"verified: {target} holds version 1" in done.output
        synced = runner.invoke(cli, ["reconcile", robot["name"]])
        assert synced.exit_code == 0, synced.output
        row = next(line for line in synced.output.splitlines() if "in_sync" in line)
        assert row.split()[0] == "torch", synced.output  # the tool's name, not its id
        assert target in row
        assert "…" not in synced.output
        assert f"robot {robot['name']}: in_sync" in synced.output


def test_a_tool_or_robot_no_one_has_is_named_in_the_refusal(api: Api, runner: CliRunner) -> None:
    api.robot("cell12-kr16")
    gone = runner.invoke(cli, ["deploy", "cell12-kr16/no-such-tool"])
    assert gone.exit_code == 5, gone.output
    assert "no tool with id or name 'cell12-kr16/no-such-tool'" in gone.output
    nobody = runner.invoke(cli, ["reconcile", "no-such-robot"])
    assert nobody.exit_code == 5, nobody.output
    assert "no robot with id or name 'no-such-robot'" in nobody.output


def test_help_says_the_exit_codes() -> None:
    for command in ("deploy", "reconcile"):
        shown = CliRunner().invoke(cli, [command, "--help"], env={"COLUMNS": "200"})
        said = " ".join(shown.output.split())
        assert "8 mismatch / drifted" in said
        assert "3 controller unreachable" in said
        assert "2 bad use" in said


def test_no_outcome_of_deploy_or_reconcile_exits_as_bad_use_or_a_refusal(
    runner: CliRunner,
) -> None:
    """Issue 51: reconcile exited 2 for drifted (and deploy for a read-back mismatch), which
    typer also exits with for bad use (an unknown option, a missing argument): a cell PC's
    script read a typo in its own command line as 'the controller drifted'. The outcomes'
    codes are their own, apart from the codes every command shares (as check --capture's 7)."""
    outcomes = {EXIT_DRIFTED, EXIT_CONTROLLER_UNREACHABLE}
    shared = {EXIT_BAD_USE, EXIT_REFUSED, EXIT_NOT_FOUND, EXIT_UNREACHABLE}
    assert outcomes & shared == set(), outcomes & shared
    for typo in (["reconcile", "r1", "--robto"], ["deploy", "t1", "--reson", "x"], ["reconcile"]):
        used = runner.invoke(cli, typo)
        assert used.exit_code == EXIT_BAD_USE, used.output


def test_deploy_says_in_words_what_the_controller_may_hold_and_keeps_the_reason(
    api: Api, runner: CliRunner
) -> None:
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        tool_id = ids["tool"]["id"]
        r.sim.fault = go_silent("after", WRITE_REQUEST["kuka_kvp"])
        lost = runner.invoke(cli, ["deploy", tool_id, "--reason", "new torch neck"])
        assert lost.exit_code == 3, lost.output
        assert (
            "written, not confirmed: the controller may hold v1 or what it held before; "
            "the next reconcile round will tell" in lost.output
        )
        assert "nothing was written" not in lost.output
        first = api.get(f"/v1/tools/{tool_id}/deployments").json()["items"][0]["id"]
        assert f"deployment {first}: unverified" in lost.output
        r.sim.stalled = False
        r.sim.fault = go_silent("before", f"read $LOAD_DATA[{SLOT}]", nth=2)
        kept = runner.invoke(cli, ["deploy", tool_id])
        assert kept.exit_code == 3, kept.output
        assert "nothing was written: the controller still holds what it held" in kept.output
        second = api.get(f"/v1/tools/{tool_id}/deployments").json()["items"][0]["id"]
        assert f"deployment {second}: not_written" in kept.output
        r.sim.stalled = False
        done = runner.invoke(cli, ["deploy", tool_id, "--reason", "new torch neck"])
        assert done.exit_code == 0, done.output
        assert "  reason     new torch neck\n" in done.output
        listed = api.get(f"/v1/tools/{tool_id}/deployments").json()["items"]
        assert [d["reason"] for d in listed] == ["new torch neck", None, "new torch neck"]
