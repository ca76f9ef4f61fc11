"""Which TCP each robot moves by (contract v1.3 fleet `live`): the reconcile rounds read the
live tool from the controller (KUKA $ACT_TOOL and $TOOL on the simulator), and the fleet
rows say whether it is the tool's active version, an older one, another tool's or a frame no
version has, with the attention codes moving_by_stale_version and moving_by_unknown_tcp.
A controller that does not say (ABB) leaves every row `unread`."""

from __future__ import annotations

import csv
import io
import time
from typing import Any

import pytest
from sqlalchemy import text

from app.storage.db import get_engine
from tests.api.controller_rigs import SLOT, Rig, rig
from tests.api.test_deployments import (
    ACTIVE_POSITION,
    ACTIVE_Q,
    PREVIOUS_POSITION,
    PREVIOUS_Q,
    _setup,
    secret_key,  # noqa: F401 (a fixture: ABB's password is stored under it)
)
from tests.conftest import Api
from tests.polling import wait_for

INTERVAL_S = 0.5
#: A frame no version of the tools below has.
ELSEWHERE = ([40.0, 40.0, 300.0], [1.0, 0.0, 0.0, 0.0])


def _calibrate(api: Api, tool_id: str, position: list[float], quaternion: list[float]) -> None:
    tcp = {"position_mm": position, "quaternion": quaternion}
    body = {"method": "manual", "tcp": tcp, "activate": "always"}
    done = api.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate")
    assert done.status_code == 201, done.text


def _torch_v1_v2(api: Api, r: Rig) -> dict[str, Any]:
    """A robot on the rig's controller with a tool in SLOT: v1 PREVIOUS, v2 ACTIVE (active)."""
    ids = _setup(api, r, calibrated=False)
    _calibrate(api, ids["tool"]["id"], PREVIOUS_POSITION, PREVIOUS_Q)
    _calibrate(api, ids["tool"]["id"], ACTIVE_POSITION, ACTIVE_Q)
    return ids


def _rows(api: Api, robot_id: str, **params: str) -> dict[str, dict[str, Any]]:
    got = api.get("/v1/tools", params={"robot_id": robot_id, **params})
    assert got.status_code == 200, got.text
    return {row["name"]: row for row in got.json()["items"]}


def _reconcile(api: Api, robot_id: str) -> dict[str, Any]:
    done = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    assert done.status_code == 200, done.text
    return dict(done.json())


def _live_events(robot_id: str) -> list[dict[str, Any]]:
    with get_engine().connect() as conn:
        rows = conn.execute(
            text(
                "SELECT details FROM audit_events WHERE robot_id = :r "
                "AND action = 'robot.live_tool' ORDER BY id"
            ),
            {"r": robot_id},
        )
        return [r.details if isinstance(r.details, dict) else _json(r.details) for r in rows]


def _json(value: str) -> dict[str, Any]:
    import json

    return dict(json.loads(value))


@pytest.fixture
def watching(monkeypatch: pytest.MonkeyPatch) -> float:
    monkeypatch.setenv("TCPCAL_RECONCILE_INTERVAL_S", str(INTERVAL_S))
    return INTERVAL_S


def test_a_robot_set_to_an_older_version_shows_on_the_fleet_within_one_interval(
    watching: float, api: Api
) -> None:
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)  # $TOOL_DATA[SLOT] holds v2
        r.sim.select_tool(SLOT)

        def live_is(state: str) -> bool:
            return bool(_rows(api, robot_id)["t1"]["live"]["state"] == state)

        def settled() -> bool:
            # a round may have read the tool table before the edit and the pose after it
            row = _rows(api, robot_id)["t1"]
            controller = row["controller"] or {}
            return bool(row["live"]["state"] == "active" and controller.get("state") == "in_sync")

        wait_for(settled, 2 * watching + 1.0, "moving by the active v2, in sync")
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["version"] == 2
        assert row["live"]["tool_id"] == tool_id
        assert row["attention"] == []
        # A program sets $TOOL to v1's values: the tool table still holds v2 (in sync), but
        # the robot moves by v1.
        r.sim.set_tool_frame(*r.native_of(PREVIOUS_POSITION, PREVIOUS_Q))
        started = time.monotonic()
        wait_for(lambda: live_is("stale_version"), watching + 2.0, "moving by v1")
        took = time.monotonic() - started
        assert took <= watching + 1.0, took  # the next round, plus its read (ms on a loaded box)
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["version"] == 1
        assert row["attention"] == ["moving_by_stale_version"]
        assert row["controller"]["state"] == "in_sync"
        flagged = _rows(api, robot_id, attention="true")
        assert list(flagged) == ["t1"]
        time.sleep(3 * watching)  # more rounds find the same: no more events
        # (a round before the pendant edit may have found the bare flange: events[:-2])
        events = _live_events(robot_id)
        assert [e["matches"] for e in events[-2:]] == [
            [{"tool_id": tool_id, "version": 2, "active": True}],
            [{"tool_id": tool_id, "version": 1, "active": False}],
        ]
        assert events[-1]["number"] is None  # $ACT_TOOL -1: $TOOL set without a tool number
        assert events[-1]["previous"]["number"] == SLOT
        assert all(e["matches"] == [] for e in events[:-2]), events


def test_an_unknown_frame_is_blamed_on_the_tool_in_the_live_slot(api: Api) -> None:
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id = ids["robot"]["id"]
        other = api.tool(robot_id, "gripper", slot=SLOT + 1)["id"]
        _calibrate(api, other, *ELSEWHERE)  # the gripper's v1 is the frame below, shifted
        r.sim.set_tool(SLOT, *r.native_of([0.0, 0.0, 99.0], [1.0, 0.0, 0.0, 0.0]))
        r.sim.select_tool(SLOT)
        _reconcile(api, robot_id)
        rows = _rows(api, robot_id)
        assert rows["t1"]["live"]["state"] == "unknown"
        assert rows["gripper"]["live"]["state"] == "unknown"
        assert "moving_by_unknown_tcp" in rows["t1"]["attention"]
        assert "moving_by_unknown_tcp" not in rows["gripper"]["attention"]
        # no tool number ($TOOL set by a program): any of the robot's tools may be it
        r.sim.set_tool_frame(*r.native_of([0.0, 0.0, 99.0], [1.0, 0.0, 0.0, 0.0]))
        _reconcile(api, robot_id)
        rows = _rows(api, robot_id)
        assert "moving_by_unknown_tcp" in rows["t1"]["attention"]
        assert "moving_by_unknown_tcp" in rows["gripper"]["attention"]
        # the gripper's own frame in the torch's slot: other_tool for the torch
        r.sim.set_tool(SLOT, *r.native_of(*ELSEWHERE))
        r.sim.select_tool(SLOT)
        live = _reconcile(api, robot_id)["live_tool"]
        assert live["number"] == SLOT
        assert live["frame"]["position_mm"] == ELSEWHERE[0]
        assert live["matches"] == [{"tool_id": other, "version": 1, "active": True}]
        rows = _rows(api, robot_id)
        assert rows["t1"]["live"] | {"checked_at": None} == {
            "state": "other_tool",
            "version": 1,
            "tool_id": other,
            "checked_at": None,
            "number": SLOT,
            "no_tool": False,
        }
        assert rows["gripper"]["live"]["state"] == "active"
        assert "moving_by_unknown_tcp" not in rows["t1"]["attention"]
        assert "moving_by_stale_version" not in rows["t1"]["attention"]


def test_every_version_equal_to_the_live_frame_is_named(api: Api) -> None:
    """v3 is v1's frame again (a rollback calibrated anew): the robot moving by it moves by
    both, and LiveTool.matches names both, v1 inactive and v3 active; the fleet row is
    `active` at v3, not `stale_version` at v1."""
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        _calibrate(api, tool_id, PREVIOUS_POSITION, PREVIOUS_Q)  # v3 = v1, active
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
        r.sim.select_tool(SLOT)
        live = _reconcile(api, robot_id)["live_tool"]
        assert live["matches"] == [
            {"tool_id": tool_id, "version": 1, "active": False},
            {"tool_id": tool_id, "version": 3, "active": True},
        ]
        pose = api.get(f"/v1/robots/{robot_id}/controller/pose", scope="calibrate")
        assert pose.status_code == 200, pose.text
        assert pose.json()["live_tool"]["matches"] == live["matches"]
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["state"], row["live"]["version"]) == ("active", 3)
        assert row["attention"] == []
        assert _live_events(robot_id)[-1]["matches"] == live["matches"]


@pytest.mark.parametrize("protocol", ["abb_rws1", "abb_rws2"])
def test_abb_is_unread(api: Api, protocol: str) -> None:
    with rig(protocol) as r:
        ids = _torch_v1_v2(api, r)
        robot_id = ids["robot"]["id"]
        never = _rows(api, robot_id)["t1"]["live"]
        assert never == {
            "state": "unread",
            "version": None,
            "tool_id": None,
            "checked_at": None,
            "number": None,
            "no_tool": False,
        }
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)  # the controller holds v1
        done = _reconcile(api, robot_id)
        # RWS answers the pose but names no tooldata: read, and nothing to match
        assert done["live_tool"] == {"number": None, "frame": None, "matches": []}
        assert done["live_tool_error"] is None
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["state"] == "unread"
        assert row["live"]["checked_at"] is not None
        assert not {"moving_by_stale_version", "moving_by_unknown_tcp"} & set(row["attention"])
        [event] = _live_events(robot_id)
        assert event["read"] is False
        assert event["matches"] == []


def test_the_csv_carries_the_live_state(api: Api) -> None:
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id = ids["robot"]["id"]
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
        r.sim.select_tool(SLOT)
        _reconcile(api, robot_id)
        got = api.get("/v1/tools", params={"robot_id": robot_id}, headers={"Accept": "text/csv"})
        [line] = list(csv.DictReader(io.StringIO(got.text)))
        assert (line["live_state"], line["live_version"]) == ("stale_version", "1")
        assert line["live_checked_at"].startswith("20")
        assert "moving_by_stale_version" in line["attention"].split(";")


def test_fanuc_moves_by_its_active_utool(api: Api) -> None:
    with rig("fanuc_rmi") as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)  # UTOOL[SLOT] holds v1
        r.sim.select(uframe=0, utool=SLOT)
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["state"], row["live"]["version"]) == ("stale_version", 1)
        assert row["attention"] == ["controller_drifted", "moving_by_stale_version"]
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert row["live"] | {"checked_at": None} == {
            "state": "active",
            "version": 2,
            "tool_id": tool_id,
            "checked_at": None,
            "number": SLOT,
            "no_tool": False,
        }
        assert row["attention"] == []
        # UTOOL 1, which no tool of tcpcal's holds, and whose frame no version has
        r.sim.select(uframe=0, utool=1)
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["state"] == "unknown"
        assert row["attention"] == ["moving_by_unknown_tcp"]
        assert [e["number"] for e in _live_events(robot_id)] == [SLOT, SLOT, 1]


def test_a_refused_pose_read_leaves_the_live_tool_unread_and_the_tools_judged(api: Api) -> None:
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id = ids["robot"]["id"]
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)
        r.sim.select_tool(SLOT)
        _reconcile(api, robot_id)
        assert _rows(api, robot_id)["t1"]["live"]["state"] == "active"
        r.sim.ipo_mode = "#TCP"  # external TCP: the KRC's $POS_ACT is not a tool on the flange
        done = _reconcile(api, robot_id)
        assert done["tools"][0]["state"] == "in_sync"
        assert done["live_tool"] is None
        assert "$IPO_MODE" in done["live_tool_error"]
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["state"] == "unread"
        assert row["attention"] == []
        event = _live_events(robot_id)[-1]
        assert event["read"] is False
        assert "$IPO_MODE" in event["error"], event
        assert event["previous"]["matches"] == [{"tool_id": ids["tool"]["id"], "version": 2}]


def test_an_unreachable_controller_leaves_the_live_tool_unread_saying_where(api: Api) -> None:
    """What the robot moved by before the controller went silent is not claimed after it:
    the row is unread, the stale claim and its attention code go, the reconcile and the
    audit event say which address did not answer."""
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id = ids["robot"]["id"]
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
        r.sim.select_tool(SLOT)
        _reconcile(api, robot_id)
        assert _rows(api, robot_id)["t1"]["live"]["state"] == "stale_version"
        r.sim.stop()
        done = _reconcile(api, robot_id)
        assert done["live_tool"] is None
        assert done["live_tool_error"].startswith(f"127.0.0.1:{r.sim.port}: "), done
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["state"] == "unread"
        assert row["live"]["checked_at"] is not None
        assert "moving_by_stale_version" not in row["attention"]
        event = _live_events(robot_id)[-1]
        assert event["read"] is False
        assert event["error"] == done["live_tool_error"]


def test_a_robot_whose_controller_is_removed_is_unread_again(api: Api) -> None:
    with rig("kuka_kvp") as r:
        ids = _torch_v1_v2(api, r)
        robot_id = ids["robot"]["id"]
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
        r.sim.select_tool(SLOT)
        _reconcile(api, robot_id)
        assert _rows(api, robot_id)["t1"]["live"]["state"] == "stale_version"
        gone = api.request("DELETE", f"/v1/robots/{robot_id}/controller", "admin")
        assert gone.status_code == 204, gone.text
        row = _rows(api, robot_id)["t1"]
        # nothing is known of what it moves by: no stale claim, no attention
        assert row["live"] == {
            "state": "unread",
            "version": None,
            "tool_id": None,
            "checked_at": None,
            "number": None,
            "no_tool": False,
        }
        assert row["attention"] == []


def test_yaskawa_moves_by_the_tool_number_its_position_read_reports(api: Api) -> None:
    """The position read (0x75) says which tool the robot moves by; its frame is that tool's
    block of TOOL.CND: the live tool is named, on the fleet and in the pose read."""
    with rig("yaskawa_hses") as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)  # tool 3 of TOOL.CND holds v1
        r.sim.select_tool(SLOT)
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["state"], row["live"]["version"]) == ("stale_version", 1)
        assert row["attention"] == ["controller_drifted", "moving_by_stale_version"]
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["state"], row["live"]["version"]) == ("active", 2)
        assert row["attention"] == []
        pose = api.get(f"/v1/robots/{robot_id}/controller/pose", scope="calibrate")
        assert pose.status_code == 200, pose.text
        live = pose.json()["live_tool"]
        assert live["number"] == SLOT
        assert live["matches"] == [{"tool_id": tool_id, "version": 2, "active": True}]
        assert pose.json()["readings"][f"TOOL.CND //TOOL {SLOT}"].startswith("12.500,-3.250,")
        # tool 1, which no tool of tcpcal's holds, and whose frame (the flange) no version has
        r.sim.select_tool(1)
        _reconcile(api, robot_id)
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["state"] == "unknown"
        assert row["attention"] == ["moving_by_unknown_tcp"]
        assert [e["number"] for e in _live_events(robot_id)] == [SLOT, SLOT, 1]


def test_techman_moves_by_its_current_tcp_and_a_project_start_sets_its_own(
    watching: float, api: Api
) -> None:
    """A TM robot moves by its current TCP (TCP_Value), which a deployment sets for the
    running project only (scope live): the next project start sets the TCP the project was
    written with. Here that is v1's values, a TCP of the robot's list named "torch_v1": the
    next round flags the robot as moving by the stale v1, and the pose read names it."""
    with rig("techman") as r:
        ids = _torch_v1_v2(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        deployed = api.post(f"/v1/tools/{tool_id}/deployments", {}, scope="calibrate")
        assert deployed.status_code == 201, deployed.text
        assert (deployed.json()["scope"], deployed.json()["target"]) == ("live", "current TCP")

        def live_is(state: str) -> bool:
            return bool(_rows(api, robot_id)["t1"]["live"]["state"] == state)

        wait_for(lambda: live_is("active"), 2 * watching + 1.0, "moving by the active v2")
        row = _rows(api, robot_id)["t1"]
        assert (row["live"]["version"], row["live"]["tool_id"]) == (2, tool_id)
        assert row["controller"]["state"] == "in_sync"
        assert row["attention"] == []
        r.sim.add_tcp("torch_v1", tuple(r.native_of(PREVIOUS_POSITION, PREVIOUS_Q)))
        r.sim.project_tcp = "torch_v1"
        r.sim.start_project()  # the operator presses Play: the project sets its own TCP
        started = time.monotonic()
        wait_for(lambda: live_is("stale_version"), watching + 2.0, "moving by v1")
        took = time.monotonic() - started
        assert took <= watching + 1.0, took  # the next round, plus its read
        row = _rows(api, robot_id)["t1"]
        assert row["live"]["version"] == 1
        assert row["controller"]["state"] == "drifted"  # the live TCP is not the active v2
        assert row["attention"] == ["controller_drifted", "moving_by_stale_version"]
        pose = api.get(f"/v1/robots/{robot_id}/controller/pose", scope="calibrate")
        assert pose.status_code == 200, pose.text
        live = pose.json()["live_tool"]
        assert live["number"] is None  # a TM robot's TCP has a name, not a number
        assert live["matches"] == [{"tool_id": tool_id, "version": 1, "active": False}]
        assert pose.json()["readings"]["TCP_Name"] == '"torch_v1"'
        events = _live_events(robot_id)
        assert events[-1]["matches"] == [{"tool_id": tool_id, "version": 1, "active": False}]
