"""Deployment `scope` and the one live TCP (contract v1.3, "More controllers"): a deployment
is `stored` where the controller keeps it (KUKA, FANUC, ABB, Yaskawa) and `live` where it
holds only for the running program (UR, Techman). Such a robot has one live TCP: reconcile
judges the tool deployed to it last (in_sync / drifted against its active version) and
reports its other tools `not_live`; the fleet, /metrics, the CLI and the console say so.

The live robot here is a fake ur_rtde controller holding one TCP (what `tcp_offset` is on a
UR and the current TCP on a Techman), put behind the services' `connect` until the ur_rtde
connector lands; the stored one is the KUKA simulator (tests/controllers/kuka_sim.py)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import pytest
from prometheus_client.parser import text_string_to_metric_families
from sqlalchemy import text

from app.storage.db import get_engine
from app.vendors.connector import (
    ClosingSession,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    Frame,
    LiveTool,
    PoseReading,
    ToolTarget,
)
from app.vendors.registry import where
from app.vendors.tool import ToolData
from tests.conftest import Api
from tests.controllers.kuka_sim import KukaSimulator

IDENTITY = (1.0, 0.0, 0.0, 0.0)


@dataclass
class LiveController:
    """A controller with one live TCP: every tool is written to it and read from it."""

    tcp: ToolData = field(default_factory=lambda: ToolData((0.0, 0.0, 0.0), IDENTITY))
    reachable: bool = True
    refuse_writes: bool = False
    writes: int = 0
    #: called as the round reads the live tool (another request running meanwhile)
    during_pose_read: Callable[[], None] | None = None

    def connect(self, settings: ControllerSettings) -> LiveSession:
        if not self.reachable:
            raise ControllerUnreachable(f"connection to {where(settings)} refused")
        return LiveSession(self)

    def program_start(self, position_mm: tuple[float, float, float]) -> None:
        """A program that sets its own TCP starts (or the pendant changes it)."""
        self.tcp = ToolData(position_mm, IDENTITY)


class LiveSession(ClosingSession):
    protocol = "ur_rtde"

    def __init__(self, controller: LiveController) -> None:
        self.controller = controller

    def describe(self, target: ToolTarget) -> str:
        return "tcp_offset"

    def read_tool(self, target: ToolTarget) -> ToolData:
        return self.controller.tcp

    def write_tool(self, target: ToolTarget, data: ToolData) -> None:
        if self.controller.refuse_writes:
            raise ControllerRefused("refused", controller_message="C210: local control")
        self.controller.writes += 1
        self.controller.tcp = ToolData(data.position_mm, data.quaternion)

    def read_pose(self) -> PoseReading:
        hook, self.controller.during_pose_read = self.controller.during_pose_read, None
        if hook is not None:
            hook()
        tcp = self.controller.tcp
        return PoseReading(
            flange=Frame((400.0, 0.0, 500.0), IDENTITY),
            joints_deg=None,
            live_tool=LiveTool(None, Frame(tcp.position_mm, tcp.quaternion)),
            readings={},
        )

    def close(self) -> None:
        pass


@pytest.fixture
def live(monkeypatch: pytest.MonkeyPatch) -> LiveController:
    """The fake live-TCP controller behind the services' `connect` for ur_rtde."""
    from app.vendors.registry import connect as real_connect

    controller = LiveController()

    def connect(settings: ControllerSettings) -> Any:
        if settings.protocol == "ur_rtde":
            return controller.connect(settings)
        return real_connect(settings)

    monkeypatch.setattr("app.services.robots.connection.has_connector", lambda protocol: True)
    for module in ("reconcile", "deployments"):
        monkeypatch.setattr(f"app.services.controllers.{module}.connect", connect)
    return controller


@dataclass
class Cell:
    robot: dict[str, Any]
    torch: dict[str, Any]
    gripper: dict[str, Any]


def _cell(api: Api) -> Cell:
    robot = api.robot("ur10e", vendor="Universal Robots")
    put = api.request(
        "PUT",
        f"/v1/robots/{robot['id']}/controller",
        "admin",
        json={"protocol": "ur_rtde", "host": "127.0.0.1", "timeout_s": 1},
    )
    assert put.status_code == 200, put.text
    assert put.json()["scope"] == "live"
    torch = api.tool(robot["id"], "torch")
    gripper = api.tool(robot["id"], "gripper")
    api.manual(torch["id"], [0.0, 0.0, 150.0])
    api.manual(gripper["id"], [0.0, 40.0, 90.0])
    return Cell(robot, torch, gripper)


def _deploy(api: Api, tool_id: str) -> Any:
    return api.post(f"/v1/tools/{tool_id}/deployments", {}, scope="calibrate")


def _reconcile(api: Api, robot_id: str) -> dict[str, Any]:
    r = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    assert r.status_code == 200, r.text
    return dict(r.json())


def _states(answer: dict[str, Any], cell: Cell) -> dict[str, str]:
    names = {cell.torch["id"]: "torch", cell.gripper["id"]: "gripper"}
    return {names[t["tool_id"]]: t["state"] for t in answer["tools"]}


def _fleet(api: Api, robot_id: str) -> dict[str, dict[str, Any]]:
    rows = api.get(f"/v1/tools?robot_id={robot_id}").json()["items"]
    return {row["name"]: row for row in rows}


def _events(robot_id: str) -> list[tuple[str, str | None]]:
    with get_engine().connect() as conn:
        rows = conn.execute(
            text("SELECT action, tool_id FROM audit_events WHERE robot_id = :r ORDER BY id"),
            {"r": robot_id},
        )
        return [(r.action, r.tool_id) for r in rows if r.action.startswith("controller.")]


def test_a_deployment_says_its_scope_by_protocol(api: Api, live: LiveController) -> None:
    """ur_rtde: live (in the answer, the list and the stored row); kuka_kvp: stored."""
    cell = _cell(api)
    r = _deploy(api, cell.torch["id"])
    assert r.status_code == 201, r.text
    assert (r.json()["scope"], r.json()["target"], r.json()["status"]) == (
        "live",
        "tcp_offset",
        "verified",
    )
    listed = api.get(f"/v1/tools/{cell.torch['id']}/deployments").json()["items"]
    assert listed[0]["scope"] == "live"
    with KukaSimulator() as krc:
        robot = api.robot("kr16")
        body = {"protocol": "kuka_kvp", "host": krc.host, "port": krc.port, "timeout_s": 1}
        put = api.request("PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=body)
        assert put.json()["scope"] == "stored"
        tool = api.tool(robot["id"], "spindle", slot=3)
        api.manual(tool["id"], [0.0, 0.0, 200.0])
        r = _deploy(api, tool["id"])
        assert r.status_code == 201, r.text
        assert r.json()["scope"] == "stored"
        assert _reconcile(api, robot["id"])["scope"] == "stored"


def test_reconcile_judges_the_tool_deployed_last_and_the_others_are_not_live(
    api: Api, live: LiveController
) -> None:
    cell = _cell(api)
    robot_id = cell.robot["id"]
    # Nothing deployed yet: no tool is the live one, and the robot is reached.
    answer = _reconcile(api, robot_id)
    assert answer["scope"] == "live"
    assert _states(answer, cell) == {"torch": "not_live", "gripper": "not_live"}
    assert answer["state"] == "in_sync"
    # The torch deployed: judged in sync; the gripper not live, in the fleet at once.
    assert _deploy(api, cell.torch["id"]).status_code == 201
    fleet = _fleet(api, robot_id)
    assert fleet["torch"]["controller"]["state"] == "in_sync"
    assert fleet["gripper"]["controller"]["state"] == "not_live"
    answer = _reconcile(api, robot_id)
    assert _states(answer, cell) == {"torch": "in_sync", "gripper": "not_live"}
    gripper = next(t for t in answer["tools"] if t["tool_id"] == cell.gripper["id"])
    assert gripper["controller"] is None
    assert gripper["deviation_mm"] is None
    assert gripper["active"]["version"] == 1
    assert [m["tool_id"] for m in answer["live_tool"]["matches"]] == [cell.torch["id"]]
    # A program start sets its own TCP: the torch drifted, the gripper still not judged.
    live.program_start((0.0, 0.0, 151.0))
    answer = _reconcile(api, robot_id)
    assert _states(answer, cell) == {"torch": "drifted", "gripper": "not_live"}
    assert answer["state"] == "drifted"
    fleet = _fleet(api, robot_id)
    assert "controller_drifted" in fleet["torch"]["attention"]
    assert not {"controller_drifted", "controller_unreachable"} & set(fleet["gripper"]["attention"])
    # The gripper deployed: now it is judged, the torch is not live (in the fleet at once).
    assert _deploy(api, cell.gripper["id"]).status_code == 201
    fleet = _fleet(api, robot_id)
    assert fleet["torch"]["controller"]["state"] == "not_live"
    assert "controller_drifted" not in fleet["torch"]["attention"]
    assert _states(_reconcile(api, robot_id), cell) == {"torch": "not_live", "gripper": "in_sync"}
    assert _fleet(api, robot_id)["torch"]["controller"]["state"] == "not_live"


def test_a_deployment_refused_before_the_write_leaves_the_live_tool_judged(
    api: Api, live: LiveController
) -> None:
    """A not_written attempt changed nothing on the controller: the tool deployed before it
    is still the live one."""
    cell = _cell(api)
    assert _deploy(api, cell.torch["id"]).status_code == 201
    live.refuse_writes = True
    r = _deploy(api, cell.gripper["id"])
    assert r.status_code == 502, r.text
    assert r.json()["deployment_status"] == "not_written"
    assert _states(_reconcile(api, cell.robot["id"]), cell) == {
        "torch": "in_sync",
        "gripper": "not_live",
    }


def test_an_unreachable_live_robot_is_unreachable_even_with_nothing_deployed(
    api: Api, live: LiveController
) -> None:
    """A controller not reached says nothing of which tool the robot moves by: every tool of
    the robot is unreachable, saying where, and the fleet flags each (not_live would hide a
    dead controller of a robot nothing was deployed to yet: no row flagged at all)."""
    cell = _cell(api)
    robot_id = cell.robot["id"]
    address = "127.0.0.1 (rtde 30004, secondary 30002)"
    live.reachable = False
    answer = _reconcile(api, robot_id)
    assert answer["state"] == "unreachable"
    assert _states(answer, cell) == {"torch": "unreachable", "gripper": "unreachable"}
    assert all(address in t["error"] for t in answer["tools"]), answer["tools"]
    assert address in answer["live_tool_error"]
    fleet = _fleet(api, robot_id)
    assert [fleet[name]["attention"] for name in ("torch", "gripper")] == [
        ["controller_unreachable"],
        ["controller_unreachable"],
    ]
    # Reached again: nothing deployed, no tool is the live one, nothing flagged.
    live.reachable = True
    assert _states(_reconcile(api, robot_id), cell) == {
        "torch": "not_live",
        "gripper": "not_live",
    }
    assert "controller_unreachable" not in _fleet(api, robot_id)["gripper"]["attention"]
    assert _deploy(api, cell.torch["id"]).status_code == 201
    live.reachable = False
    answer = _reconcile(api, robot_id)
    assert _states(answer, cell) == {"torch": "unreachable", "gripper": "unreachable"}
    assert ("controller.unreachable", cell.gripper["id"]) in _events(robot_id)


def test_a_deployment_during_a_round_makes_the_round_judge_the_new_live_tool(
    api: Api, live: LiveController
) -> None:
    """The torch is live; while a round reads, the gripper is deployed. What the round read
    was the torch's to judge: it reads again, judges the gripper and records no drift of the
    torch (which the controller no longer holds because it is not the live one)."""
    from app.security.auth import Principal
    from app.services.controllers import deployments
    from app.services.tools.subject import TOOL

    cell = _cell(api)
    assert _deploy(api, cell.torch["id"]).status_code == 201

    def deploy_the_gripper() -> None:
        actor = Principal(key_id="test", name="bob", scope="calibrate")
        done = deployments.attempt(TOOL, subject_id=cell.gripper["id"], actor=actor, reason=None)
        assert done.error is None

    live.during_pose_read = deploy_the_gripper
    answer = _reconcile(api, cell.robot["id"])
    assert _states(answer, cell) == {"torch": "not_live", "gripper": "in_sync"}
    assert ("controller.drifted", cell.torch["id"]) not in _events(cell.robot["id"])


def test_metrics_count_not_live_tools(api: Api, live: LiveController) -> None:
    cell = _cell(api)
    assert _deploy(api, cell.torch["id"]).status_code == 201
    samples = {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(api.get("/metrics").text)
        for s in family.samples
    }
    assert samples[("tcpcal_fleet_tools_controller_state", (("state", "not_live"),))] >= 1


def test_the_cli_says_what_live_means(
    api: Api, live: LiveController, monkeypatch: pytest.MonkeyPatch
) -> None:

    from app.cli import cli
    from app.cli.controllers import EXIT_CONTROLLER_UNREACHABLE
    from tests.cli.in_process import cli_as

    runner = cli_as("calibrate", api, monkeypatch)
    cell = _cell(api)
    done = runner.invoke(cli, ["deploy", cell.torch["id"]])
    assert done.exit_code == 0, done.output
    assert "verified: tcp_offset holds version 1" in done.output
    assert "the next program start sets its own TCP" in done.output
    done = runner.invoke(cli, ["reconcile", cell.robot["id"]])
    assert done.exit_code == 0, done.output
    assert "not_live" in done.output
    assert "one live TCP: judged by torch, deployed to it last" in done.output
    assert "the next program start sets its own TCP" in done.output
    live.reachable = False
    done = runner.invoke(cli, ["reconcile", cell.robot["id"]])
    assert done.exit_code == EXIT_CONTROLLER_UNREACHABLE, done.output
    assert "its controller could not be read, so no tool was judged" in done.output
    assert "judged by torch" not in done.output
