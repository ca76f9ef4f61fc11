"""`tcpcal tools` says what a fleet row holds (issue 51): a re-check that corrected the TCP is
"corrected to v2", not "FAILED"; a controller state read before the active version changed
names the version it compared and when, not "in sync" with the active one."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from app.cli import cli
from tests.api.controller_rigs import rig
from tests.api.test_capture_controllers import SETUPS
from tests.api.test_capture_controllers import secret_key as secret_key  # autouse
from tests.api.test_recheck_controllers import (
    ACTIVE_POSITION,
    ACTIVE_Q,
    MOVED,
    recheck,
    stand_at_reference,
    tool_at_reference,
)
from tests.cli.in_process import cli_as
from tests.conftest import Api


@pytest.fixture
def runner(api: Api, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    """The commands talk to the in-process app (its test transport) with a read key."""

    return cli_as("read", api, monkeypatch)


def test_tools_says_a_correction_and_which_version_the_controller_was_compared_with(
    api: Api, runner: CliRunner
) -> None:
    with rig("kuka_kvp") as r:
        cell = SETUPS["kuka_kvp"](r)
        tool, point_id = tool_at_reference(api, r)
        stand_at_reference(cell, np.asarray(ACTIVE_POSITION) + MOVED)
        done = recheck(api, tool["id"], point_id)
        assert done.json()["verdict"] == "corrected", done.text  # v2, deployed: in sync
        listed = runner.invoke(cli, ["tools"])
        assert listed.exit_code == 0, listed.output
        [line] = [row for row in listed.output.splitlines() if tool["id"] in row]
        assert "corrected to v2" in line, line
        assert "FAILED" not in line, line
        assert " in sync " in line, line
        assert "not compared" not in line, line
        moved = [ACTIVE_POSITION[0] + 0.3, *ACTIVE_POSITION[1:]]
        body = {"method": "manual", "tcp": {"position_mm": moved, "quaternion": ACTIVE_Q}}
        assert api.post(f"/v1/tools/{tool['id']}/calibrations", body, scope="calibrate").is_success
        listed = runner.invoke(cli, ["tools"])
        [line] = [row for row in listed.output.splitlines() if tool["id"] in row]
        assert "v2 in sync at " in line, line
        assert " UTC; v3 not compared yet" in line, line
