"""What a fleet row says must hold together (issue 51): a controller state read before the
active version changed names the version it compared (not "in sync" with the new one), a
deployment that read the live TCP back says what the robot now moves by, a re-check that
corrected the tool is a correction (not a failed check), and a robot standing at its bare
flange (tool 0, no tool selected) is not moving by an unknown TCP. No watcher runs here: each
row says only what the last look, deployment or check found."""

from __future__ import annotations

import pytest

from tests.api.controller_rigs import LIVE_PROTOCOLS, rig
from tests.api.test_deployments import (
    PREVIOUS_POSITION,
    PREVIOUS_Q,
    _deploy,
    secret_key,  # noqa: F401 (a fixture: ABB's password is stored under it)
)
from tests.api.test_fleet_live import _reconcile, _rows, _torch_v1_v2
from tests.conftest import Api


@pytest.mark.parametrize("protocol", sorted(LIVE_PROTOCOLS))
def test_a_verified_deployment_to_a_live_tcp_says_what_the_robot_moves_by(
    api: Api, protocol: str
) -> None:
    """The round read the robot moving by v1; v2 is then deployed and read back: the live TCP
    is v2 from the deployment on (UR tcp_offset, Techman's current TCP are what was read
    back), not the round's v1 of before it."""
    with rig(protocol) as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)  # the live TCP is v1
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["state"], row["live"]["version"]) == ("stale_version", 1)
        deployed = _deploy(api, tool_id)
        assert deployed.status_code == 201, deployed.text
        assert deployed.json()["status"] == "verified"
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["state"], row["live"]["version"]) == ("active", 2), row["live"]
        assert row["live"]["checked_at"] == deployed.json()["created_at"]
        assert "moving_by_stale_version" not in row["attention"]


def test_a_verified_deployment_to_a_stored_tool_leaves_what_the_robot_moves_by_as_read(
    api: Api,
) -> None:
    """KUKA: writing $TOOL_DATA[3] does not change $TOOL, the frame the robot moves by until a
    program selects the tool again: the round's read stands, with its time."""
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
        r.sim.select_tool(3)
        _reconcile(api, robot_id)
        before = _rows(api, robot_id)["t1"]["live"]
        assert (before["state"], before["version"]) == ("stale_version", 1)
        deployed = _deploy(api, tool_id)
        assert deployed.status_code == 201, deployed.text
        assert _rows(api, robot_id)["t1"]["live"] == before
