"""`tcpcal check TOOL --capture --reference NAME --correct` (issue 41) through typer's runner,
against the in-process app and a controller simulator: the summary sentence, the correction
(version, delta in mm, deployment status in words) and the exit codes 0 in tolerance, 1
corrected, 7 needs recalibration, 3 controller failure (2 is typer's bad use, never an
outcome). The robot stands with the tip at the
reference point as tests/api/test_recheck_controllers.py places it."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from app.cli import cli
from app.cli.http import EXIT_BAD_USE, EXIT_NOT_FOUND, EXIT_REFUSED, EXIT_UNREACHABLE
from app.cli.recheck import EXIT_CONTROLLER_FAILED, EXIT_RECALIBRATE, VERDICT_EXITS
from tests.api.controller_rigs import rig
from tests.api.test_capture_controllers import SETUPS, Cell
from tests.api.test_deployments import WRITE_REQUEST
from tests.api.test_deployments import secret_key as secret_key  # ABB's password, autouse
from tests.api.test_recheck_controllers import (
    ACTIVE_POSITION,
    CRASHED,
    MOVED,
    TABLES,
    stand_at_reference,
    tool_at_reference,
)
from tests.api.touches import row_counts
from tests.cli.test_controller_cli import runner as runner  # the CLI on the in-process app
from tests.conftest import Api
from tests.controllers.simbase import go_silent

KUKA = "kuka_kvp"


def _ready(api: Api, cell: Cell, moved: np.ndarray) -> tuple[dict[str, Any], str]:
    """A tool deployed at version 1, its robot standing with the true TCP (active + moved)
    at the reference point "pin"."""
    tool, point_id = tool_at_reference(api, cell.rig)
    stand_at_reference(cell, np.asarray(ACTIVE_POSITION) + moved)
    return tool, point_id


def _active(api: Api, tool_id: str) -> int:
    return int(api.get(f"/v1/tools/{tool_id}/tcp").json()["version"])


@pytest.mark.parametrize("protocol", [KUKA, "fanuc_rmi", "abb_rws2"])
def test_a_moved_tcp_is_corrected_exit_1(api: Api, runner: CliRunner, protocol: str) -> None:
    with rig(protocol) as r:
        cell = SETUPS[protocol](r)
        tool, _ = _ready(api, cell, MOVED)
        args = ["check", tool["id"], "--capture", "--reference", "pin", "--correct"]
        done = runner.invoke(cli, [*args, "--reason", "torch hit the clamp"])
        assert done.exit_code == 1, done.output
        assert "corrected: version 2" in done.output
        assert "read back as written" in done.output  # the summary sentence
        lines = {line.split(maxsplit=1)[0]: line.split(maxsplit=1)[1] for line in
                 done.output.splitlines() if line.startswith("  ")}  # fmt: skip
        assert lines["version"] == "v2 (was v1)"
        delta = [float(v) for v in re.findall(r"[+-]\d+\.\d{3}", lines["delta"])]
        np.testing.assert_allclose(delta, MOVED, atol=0.02)
        assert "(0.943 mm, flange frame)" in lines["delta"]
        assert lines["deployment"].startswith("verified: ")
        assert "holds version 2, read back as written" in lines["deployment"]
        assert _active(api, tool["id"]) == 2
        active = api.get(f"/v1/tools/{tool['id']}/tcp").json()["tcp"]
        r.assert_holds(active["position_mm"], active["quaternion"])


def test_in_tolerance_exit_0_and_the_point_by_id(api: Api, runner: CliRunner) -> None:
    with rig(KUKA) as r:
        tool, point_id = _ready(api, SETUPS[KUKA](r), np.zeros(3))
        counts = row_counts(("tcp_versions", "activations", "deployments"))
        done = runner.invoke(
            cli, ["check", tool["id"], "--capture", "--reference", point_id, "--correct"]
        )
        assert done.exit_code == 0, done.output
        assert "within tolerance" in done.output
        assert "version" not in [line.split()[0] for line in done.output.splitlines() if line]
        assert row_counts(("tcp_versions", "activations", "deployments")) == counts
        # the positional form of the point names it as well
        again = runner.invoke(cli, ["check", tool["id"], point_id, "--capture"])
        assert again.exit_code == 0, again.output


def test_beyond_max_correction_exit_7_nothing_changed(api: Api, runner: CliRunner) -> None:
    with rig(KUKA) as r:
        tool, _ = _ready(api, SETUPS[KUKA](r), CRASHED)
        counts, held = row_counts(TABLES), r.native()
        done = runner.invoke(
            cli, ["check", tool["id"], "--capture", "--reference", "pin", "--correct"]
        )
        assert done.exit_code == EXIT_RECALIBRATE == 7, done.output
        assert "nothing was changed: recalibrate" in done.output
        assert "version" not in done.output.split("recalibrate", 1)[1]  # no correction lines
        assert row_counts(TABLES) == counts
        assert r.native() == held
        assert _active(api, tool["id"]) == 1


def test_out_of_tolerance_without_correct_exit_7_nothing_corrected(
    api: Api, runner: CliRunner
) -> None:
    with rig(KUKA) as r:
        tool, _ = _ready(api, SETUPS[KUKA](r), MOVED)
        done = runner.invoke(cli, ["check", tool["id"], "--capture", "--reference", "pin"])
        assert done.exit_code == EXIT_RECALIBRATE, done.output
        assert "out of tolerance" in done.output
        assert _active(api, tool["id"]) == 1


def test_a_failed_deployment_exit_3_says_the_new_version_is_active(
    api: Api, runner: CliRunner
) -> None:
    with rig(KUKA) as r:
        tool, _ = _ready(api, SETUPS[KUKA](r), MOVED)
        held = r.native()
        r.sim.fault = go_silent("before", WRITE_REQUEST[KUKA])
        done = runner.invoke(
            cli, ["check", tool["id"], "--capture", "--reference", "pin", "--correct"]
        )
        assert done.exit_code == 3, done.output
        assert "failed" in done.output  # the summary: corrected in tcpcal, deployment failed
        # said as this CLI's command, not the HTTP call an API client makes (issue 51, #9)
        said = " ".join(done.output.split())
        assert f"deploy version 2 again (tcpcal deploy {tool['id']}) once it answers" in said
        assert "/v1/" not in said, said
        deployment = next(
            line for line in done.output.splitlines() if line.startswith("  deployment")
        )
        # the write was sent and never answered: it may or may not have taken
        assert "written, not confirmed: $TOOL_DATA[3] may hold version 2 or what it held" in (
            deployment
        )
        assert "did not answer within 1 s" in deployment  # the controller's error
        assert _active(api, tool["id"]) == 2  # the correction stays active, flagged
        assert r.native() == held


def test_a_controller_that_does_not_answer_exit_3(api: Api, runner: CliRunner) -> None:
    with rig(KUKA) as r:
        tool, _ = _ready(api, SETUPS[KUKA](r), MOVED)
        counts = row_counts(TABLES)
        r.sim.stop()
        done = runner.invoke(
            cli, ["check", tool["id"], "--capture", "--reference", "pin", "--correct"]
        )
        assert done.exit_code == 3, done.output
        assert "502" in done.output
        assert row_counts(TABLES) == counts


def test_bad_use_is_said_before_anything_is_sent(api: Api, runner: CliRunner) -> None:
    with rig(KUKA) as r:
        tool, _ = _ready(api, SETUPS[KUKA](r), MOVED)
        unknown = runner.invoke(cli, ["check", tool["id"], "--capture", "--reference", "anvil"])
        assert unknown.exit_code == 5, unknown.output
        assert "no reference point 'anvil' (it has: pin)" in unknown.output
        typed = runner.invoke(
            cli, ["check", tool["id"], "--capture", "--reference", "pin", "--format", "kuka_abc"]
        )
        assert typed.exit_code == 2, typed.output
        assert "leave out the poses" in typed.output
        correct_typed = runner.invoke(cli, ["check", tool["id"], "pin", "--correct"])
        assert correct_typed.exit_code == 2, correct_typed.output
        assert "--correct, --reason and --idempotency-key go with --capture" in (
            correct_typed.output
        )
        assert _active(api, tool["id"]) == 1


def test_the_help_says_the_exit_codes(runner: CliRunner) -> None:
    shown = runner.invoke(cli, ["check", "--help"])
    assert shown.exit_code == 0, shown.output
    said = " ".join(shown.output.split())
    assert "0 in tolerance; 1 corrected" in said
    assert "7 needs recalibration" in said
    assert "2 bad use" in said
    assert "3 controller failure" in said


def test_no_outcome_of_a_capture_check_exits_as_bad_use_or_a_refusal(runner: CliRunner) -> None:
    """A cell PC's script branches on the code: needs recalibration exited 2, which typer
    also exits with for bad use (an unknown option, a missing argument), so a typo in the
    script read as "recalibrate". Every verdict's code and the controller failure's are
    their own, apart from the codes every command shares."""
    outcomes = {*VERDICT_EXITS.values(), EXIT_CONTROLLER_FAILED}
    shared = {EXIT_BAD_USE, EXIT_REFUSED, EXIT_NOT_FOUND, EXIT_UNREACHABLE}
    assert outcomes & shared == set()
    typo = runner.invoke(cli, ["check", "t1", "--capture", "--refrence", "pin"])
    assert typo.exit_code == EXIT_BAD_USE, typo.output
