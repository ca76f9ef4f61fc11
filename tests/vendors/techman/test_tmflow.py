"""The Techman connector against the TMflow simulator (tests/controllers/techman_sim.py):
ChangeTCP through the Listen Node, the current TCP, flange and joints through the Ethernet
Slave, and what a real cell does to a session."""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.vendors.connector import (
    ControllerProtocolError,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    Deadline,
    ToolTarget,
)
from app.vendors.registry import connect
from app.vendors.techman.tmflow import TechmanConnector, _Channel
from app.vendors.tool import ToolData, ToolLoad
from tests.controllers.fixtures import techman_settings
from tests.controllers.helpers import angle_between_deg, random_tool
from tests.controllers.simbase import go_silent
from tests.controllers.techman_sim import TechmanSimulator, matrix

LIVE = ToolTarget()


def settings(sim: TechmanSimulator, timeout_s: float = 2.0) -> ControllerSettings:
    return techman_settings(sim, timeout_s=timeout_s)


def held_frame(sim: TechmanSimulator) -> tuple[np.ndarray, Rotation]:
    """The current TCP as the simulator holds it: position, rotation (R = Rz Ry Rx)."""
    m = matrix(sim.current_tcp()[1].values)
    return m[:3, 3], Rotation.from_matrix(m[:3, :3])


def rotation_of(q: tuple[float, ...]) -> Rotation:
    return Rotation.from_quat([q[1], q[2], q[3], q[0]])


def wait_until(condition: object, timeout_s: float = 2.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:  # type: ignore[operator]
        time.sleep(0.01)


@pytest.mark.parametrize("seed", range(5))
def test_a_written_tool_is_the_current_tcp_and_reads_back(
    techman_sim: TechmanSimulator, seed: int
) -> None:
    tool = random_tool(seed, load=False)
    with connect(settings(techman_sim)) as tm:
        tm.write_tool(LIVE, tool)
        back = tm.read_tool(LIVE)
    position, rotation = held_frame(techman_sim)
    assert_allclose(position, tool.position_mm, atol=1e-3)
    off = np.degrees((rotation.inv() * rotation_of(tool.quaternion)).magnitude())
    assert off < 1e-3
    assert_allclose(back.position_mm, tool.position_mm, atol=1e-3)
    assert angle_between_deg(back.quaternion, tool.quaternion) < 1e-3
    assert back.load is None
    script = techman_sim.scripts[-1][1]
    assert script.startswith("ChangeTCP({"), script
    assert script.endswith("\r\nQueueTag(15,0)"), script


def test_the_load_is_written_and_without_one_the_controllers_mass_is_kept(
    techman_sim: TechmanSimulator,
) -> None:
    techman_sim.set_current_tcp((0.0, 0.0, 50.0, 0.0, 0.0, 0.0), mass=2.5)
    frame = ToolData((1.0, 2.0, 150.0), (1.0, 0.0, 0.0, 0.0))
    with connect(settings(techman_sim)) as tm:
        tm.write_tool(LIVE, frame)
        assert techman_sim.current_tcp()[1].mass == 2.5
        tm.write_tool(
            LIVE, ToolData(frame.position_mm, frame.quaternion, ToolLoad(1.25, (0, 5, 60)))
        )
    held = techman_sim.current_tcp()[1]
    assert held.mass == 1.25
    assert held.inertia == (0.0, 0.0, 0.0, 0.0, 5.0, 60.0, 0.0, 0.0, 0.0)


def test_the_pose_the_joints_and_the_live_tool_in_one_read(techman_sim: TechmanSimulator) -> None:
    techman_sim.jog_flange(417.5, -122.25, 610.0, 175.0, -3.5, 88.0)
    techman_sim.set_joints(10.0, -20.0, 95.0, 5.0, 90.0, -45.0)
    techman_sim.add_tcp("Gripper", (0.0, 10.0, 120.0, 0.0, 0.0, 45.0), mass=0.8)
    techman_sim.select_tcp("Gripper")
    with connect(settings(techman_sim)) as tm:
        pose = tm.read_pose()
    expected = matrix((417.5, -122.25, 610.0, 175.0, -3.5, 88.0))
    assert_allclose(pose.flange.position_mm, expected[:3, 3], atol=1e-4)
    off = rotation_of(pose.flange.quaternion).inv() * Rotation.from_matrix(expected[:3, :3])
    assert np.degrees(off.magnitude()) < 1e-4
    assert pose.joints_deg == (10.0, -20.0, 95.0, 5.0, 90.0, -45.0)
    assert pose.live_tool.number is None
    assert pose.live_tool.frame is not None
    assert_allclose(pose.live_tool.frame.position_mm, (0.0, 10.0, 120.0), atol=1e-6)
    assert angle_between_deg(pose.live_tool.frame.quaternion, (0.92388, 0, 0, 0.382683)) < 1e-3
    assert pose.readings["TCP_Name"] == '"Gripper"'
    assert (
        pose.readings["TCP_Value"] == "{0.000000,10.000000,120.000000,0.000000,0.000000,45.000000}"
    )
    assert set(pose.readings) == {
        "Coord_Robot_Flange",
        "Joint_Angle",
        "TCP_Value",
        "TCP_Name",
        "TCP_Mass",
        "Base_Name",
        "Base_Value",
    }


def test_outside_the_listen_node_the_write_is_refused_saying_what_to_do(
    techman_sim: TechmanSimulator,
) -> None:
    techman_sim.leave_listen_node()
    with connect(settings(techman_sim)) as tm, pytest.raises(ControllerRefused) as refused:
        tm.write_tool(LIVE, random_tool(1, load=False))
    assert refused.value.write_sent  # sent: only a read tells it was not taken
    assert "$CPERR F1" in refused.value.controller_message
    assert "reach its Listen node" in str(refused.value)
    assert techman_sim.current_tcp()[1].values == (0.0,) * 6


@pytest.mark.parametrize(
    ("table", "state"),
    [
        ("all", "no project is running"),
        ("without Project_Run", "no project is running, or the running one has no Listen node"),
    ],
)
def test_no_project_running_is_a_refusal_before_anything_is_sent(
    techman_sim: TechmanSimulator, table: str, state: str
) -> None:
    if table != "all":
        techman_sim.data_table.discard("Project_Run")
    techman_sim.stop_project()
    with connect(settings(techman_sim)) as tm:
        assert tm.read_tool(LIVE).position_mm == (0.0, 0.0, 0.0)  # reads need no project
        with pytest.raises(ControllerRefused) as refused:
            tm.write_tool(LIVE, random_tool(2, load=False))
    assert not refused.value.write_sent
    assert f"Listen Node at 127.0.0.1:{techman_sim.listen_node_port}: {state};" in str(
        refused.value
    )
    assert "Play" in str(refused.value)


def test_a_line_the_node_refuses_is_named(techman_sim: TechmanSimulator) -> None:
    bad = ToolData((0.0, 0.0, 100.0), (1.0, 0.0, 0.0, 0.0), ToolLoad(-1.0, (0.0, 0.0, 0.0)))
    with connect(settings(techman_sim)) as tm, pytest.raises(ControllerRefused) as refused:
        tm.write_tool(LIVE, bad)
    assert "refused ChangeTCP({0.000000,0.000000,100.000000" in str(refused.value)
    assert refused.value.controller_message == "tcpcal1,ERROR;1"


def test_an_item_missing_from_the_data_table_names_what_to_add(
    techman_sim: TechmanSimulator,
) -> None:
    techman_sim.data_table.discard("Coord_Robot_Flange")
    with connect(settings(techman_sim)) as tm, pytest.raises(ControllerRefused) as refused:
        tm.read_pose()
    assert refused.value.controller_message == "04,NotExist;Coord_Robot_Flange"
    assert "add Coord_Robot_Flange to the Ethernet Slave's data table" in str(refused.value)


@pytest.mark.parametrize(("moment", "changed"), [("before", False), ("after", True)])
def test_silence_after_the_script_is_sent_is_write_sent_and_frees_the_node(
    techman_sim: TechmanSimulator, moment: str, changed: bool
) -> None:
    techman_sim.fault = go_silent(moment, "ChangeTCP")  # type: ignore[arg-type]
    started = time.monotonic()
    with (
        pytest.raises(ControllerUnreachable) as silent,
        connect(settings(techman_sim, timeout_s=0.5)) as tm,
    ):
        tm.write_tool(LIVE, ToolData((0.0, 0.0, 150.0), (1.0, 0.0, 0.0, 0.0)))
    assert time.monotonic() - started < 1.0
    assert silent.value.write_sent
    assert (techman_sim.current_tcp()[1].values[2] == 150.0) is changed
    wait_until(lambda: techman_sim.listen_node_clients() == 0)
    assert techman_sim.listen_node_clients() == 0  # closed: nothing holds the node
    techman_sim.stalled = False
    with connect(settings(techman_sim)) as tm:
        tm.write_tool(LIVE, ToolData((0.0, 0.0, 160.0), (1.0, 0.0, 0.0, 0.0)))
    assert techman_sim.current_tcp()[1].values[2] == 160.0


def test_a_silent_controller_fails_the_session_within_its_timeout(
    techman_sim: TechmanSimulator,
) -> None:
    techman_sim.stalled = True
    started = time.monotonic()
    with connect(settings(techman_sim, 0.4)) as tm, pytest.raises(ControllerUnreachable):
        tm.read_tool(LIVE)
    assert time.monotonic() - started < 0.9


def test_a_node_another_client_holds_is_reported_as_such(techman_sim: TechmanSimulator) -> None:
    other = socket.create_connection((techman_sim.host, techman_sim.listen_node_port))
    try:
        wait_until(lambda: techman_sim.listen_node_clients() == 1)
        with (
            pytest.raises(ControllerUnreachable) as held,
            connect(settings(techman_sim, 0.5)) as tm,
        ):
            tm.write_tool(LIVE, random_tool(4, load=False))
        assert "another client connected to it may hold it" in str(held.value)
    finally:
        other.close()


def test_the_queue_is_waited_for_within_the_deadline(techman_sim: TechmanSimulator) -> None:
    techman_sim.queue_delay_s = 0.3
    tool = ToolData((0.0, 0.0, 77.0), (1.0, 0.0, 0.0, 0.0))
    with connect(settings(techman_sim)) as tm:
        tm.write_tool(LIVE, tool)
        assert tm.read_tool(LIVE).position_mm == (0.0, 0.0, 77.0)
    techman_sim.queue_delay_s = 5.0
    with pytest.raises(ControllerUnreachable) as late, connect(settings(techman_sim, 0.5)) as tm:
        tm.write_tool(LIVE, ToolData((0.0, 0.0, 78.0), (1.0, 0.0, 0.0, 0.0)))
    assert late.value.write_sent


def test_broadcasts_between_answers_are_passed_by() -> None:
    with TechmanSimulator(broadcast_s=0.002) as busy, connect(settings(busy)) as tm:
        for z in (10.0, 20.0, 30.0):
            tm.write_tool(LIVE, ToolData((0.0, 0.0, z), (1.0, 0.0, 0.0, 0.0)))
            assert tm.read_tool(LIVE).position_mm == (0.0, 0.0, z)
            assert tm.read_pose().live_tool.frame is not None


def test_a_packet_with_a_wrong_checksum_is_not_read() -> None:
    left, right = socket.socketpair()
    try:
        channel = _Channel(left, "peer")
        right.sendall(b"$TMSVR,15,1,12,TCP_Mass=0,*00\r\n")
        with pytest.raises(ControllerProtocolError, match="wrong checksum"):
            channel.receive(Deadline(1.0))
        right.sendall(b"$TMSVR,15,1,12,TCP_Mass=0,*")  # a packet cut short: waits for more
        with pytest.raises(ControllerUnreachable, match="did not answer"):
            channel.receive(Deadline(0.2))
    finally:
        left.close()
        right.close()


def test_the_settings_name_both_ports_and_no_secret() -> None:
    with TechmanSimulator() as sim:
        text = repr(settings(sim))
        assert f"'listen_node': {sim.listen_node_port}" in text
        assert isinstance(connect(settings(sim)), TechmanConnector)
