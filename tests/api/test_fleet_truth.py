"""What a fleet row says must hold together (issue 51): a controller state read before the
active version changed names the version it compared (not "in sync" with the new one), a
deployment that read the live TCP back says what the robot now moves by, a re-check that
corrected the tool is a correction (not a failed check), and a robot standing at its bare
flange (tool 0, no tool selected) is not moving by an unknown TCP. No watcher runs here: each
row says only what the last look, deployment or check found."""

from __future__ import annotations

import numpy as np
import pytest

from tests.api.controller_rigs import LIVE_PROTOCOLS, Rig, rig
from tests.api.test_capture_controllers import SETUPS
from tests.api.test_deployments import (
    ACTIVE_POSITION,
    ACTIVE_Q,
    PREVIOUS_POSITION,
    PREVIOUS_Q,
    WRITE_REQUEST,
    _deploy,
    secret_key,  # noqa: F401 (a fixture: ABB's password is stored under it)
)
from tests.api.test_fleet_live import _calibrate, _reconcile, _rows, _torch_v1_v2
from tests.api.test_recheck_controllers import ACTIVE_POSITION as RECHECK_ACTIVE
from tests.api.test_recheck_controllers import (
    MOVED,
    recheck,
    stand_at_reference,
    tool_at_reference,
)
from tests.conftest import Api
from tests.controllers.simbase import go_silent


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


def test_a_state_read_before_the_active_version_changed_names_the_version_it_compared(
    api: Api,
) -> None:
    """The last look found $TOOL_DATA[3] in sync with v2; v3 is then activated and its
    deployment never reaches the controller: the row's controller state is still the look's,
    and says it compared v2, where, and when, so that nobody reads it as v3 in sync."""
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)
        looked = _reconcile(api, robot_id)
        _calibrate(api, tool_id, [ACTIVE_POSITION[0] + 0.8, *ACTIVE_POSITION[1:]], ACTIVE_Q)
        r.sim.stop()
        failed = _deploy(api, tool_id)
        assert failed.status_code == 502, failed.text
        assert failed.json()["deployment_status"] == "not_written"
        row = _rows(api, robot_id)["t1"]
        assert row["active_version"] == 3
        controller = row["controller"]
        assert (controller["state"], controller["deviation_mm"]) == ("in_sync", 0.0)
        assert (controller["version"], controller["target"]) == (2, "$TOOL_DATA[3]"), controller
        assert controller["checked_at"] == looked["checked_at"]


def test_a_check_that_corrected_the_tool_is_a_correction_on_the_fleet(api: Api) -> None:
    """0.8 mm off, corrected to v2 and deployed: the row's last check carries the verdict and
    the version it corrected to, not only within_tolerance false."""
    with rig("kuka_kvp") as r:
        cell = SETUPS["kuka_kvp"](r)
        tool, point_id = tool_at_reference(api, r)
        stand_at_reference(cell, np.asarray(RECHECK_ACTIVE) + MOVED)
        done = recheck(api, tool["id"], point_id)
        assert done.status_code == 201, done.text
        assert done.json()["verdict"] == "corrected"
        [row] = _rows(api, tool["robot_id"]).values()
        check = row["last_check"]
        assert check["within_tolerance"] is False
        assert (check["verdict"], check["correction_version"]) == ("corrected", 2), check
        assert "check_failed" not in row["attention"]


def _stand_at_the_flange(r: Rig) -> None:
    """The robot idles between jobs with no tool selected: KUKA $TOOL = $NULLFRAME (set by a
    program: the simulator selects numbers 1-16 only), FANUC UTOOL 0, Yaskawa tool 0 (its
    TOOL.CND block all zeros), UR tcp_offset and Techman's current TCP zero."""
    if r.protocol == "kuka_kvp":
        r.sim.set_tool_frame(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    elif r.protocol == "fanuc_rmi":
        r.sim.select(uframe=0, utool=0)
    elif r.protocol == "yaskawa_hses":
        r.sim.select_tool(0)
    else:
        r.set_behind_back([0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    "protocol", ["kuka_kvp", "fanuc_rmi", "yaskawa_hses", *sorted(LIVE_PROTOCOLS)]
)
def test_a_robot_at_its_bare_flange_has_no_tool_selected_not_an_unknown_tcp(
    api: Api, protocol: str
) -> None:
    """Tool 0 is the flange itself, where robots idle between jobs: no version has that
    frame, and none should (it is not a tool). The row says no tool is selected, and raises
    no moving_by_unknown_tcp on any tool, where each of the robot's tools had it."""
    with rig(protocol) as r:
        ids = _torch_v1_v2(api, r)
        robot_id = ids["robot"]["id"]
        api.tool(robot_id, "gripper", **({"slot": 5} if r.tool_fields else {}))
        _stand_at_the_flange(r)
        live = _reconcile(api, robot_id)["live_tool"]
        assert live["frame"] == {"position_mm": [0.0, 0.0, 0.0], "quaternion": [1.0, 0.0, 0.0, 0.0]}
        for name, row in _rows(api, robot_id).items():
            assert row["live"]["state"] == "unknown", (name, row["live"])
            assert row["live"]["no_tool"] is True, (name, row["live"])
            assert "moving_by_unknown_tcp" not in row["attention"], (name, row["attention"])
        flagged = _rows(api, robot_id, attention="true")
        assert all("moving_by_unknown_tcp" not in row["attention"] for row in flagged.values())
        # a frame no version has, in a tool the robot selects: an unknown TCP as before
        r.set_behind_back([0.0, 0.0, 99.0], [1.0, 0.0, 0.0, 0.0])
        if protocol == "kuka_kvp":
            r.sim.select_tool(3)
        elif protocol == "fanuc_rmi":
            r.sim.select(uframe=0, utool=3)
        elif protocol == "yaskawa_hses":
            r.sim.select_tool(3)
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["state"], row["live"]["no_tool"]) == ("unknown", False)
        assert "moving_by_unknown_tcp" in row["attention"]


@pytest.mark.parametrize("protocol", sorted(LIVE_PROTOCOLS))
def test_a_live_tcp_written_and_not_read_back_is_not_known(api: Api, protocol: str) -> None:
    """The controller takes the write and goes silent: the robot may move by v2 or by the
    v1 the round read before; the fleet claims neither (unread, no stale_version) until the
    next round reads it."""
    with rig(protocol) as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
        _reconcile(api, robot_id)
        assert _rows(api, robot_id)["t1"]["live"]["state"] == "stale_version"
        r.sim.fault = go_silent("after", WRITE_REQUEST[r.protocol])
        failed = _deploy(api, tool_id)
        assert failed.status_code == 502, failed.text
        assert failed.json()["deployment_status"] == "unverified"
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["state"] == "unread", row["live"]
        assert "moving_by_stale_version" not in row["attention"]
        r.sim.stalled = False  # the controller back: the next round reads it
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["state"], row["live"]["version"]) == ("active", 2), row["live"]
