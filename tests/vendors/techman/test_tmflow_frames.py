"""Techman's current base against the TMflow simulator: ChangeBase through the Listen Node,
read back from the Ethernet Slave's Base_Value, the live base (Base_Name, Base_Value) in
the pose read, refusals; cuts are tests/vendors/test_frame_cuts.py's."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.vendors.connector import UNREAD_FRAME, ControllerRefused, Frame, FrameTarget
from app.vendors.registry import connect
from tests.controllers.fixtures import techman_settings
from tests.controllers.helpers import angle_between_deg, random_frame
from tests.controllers.techman_sim import TechmanSimulator, matrix

BASE = FrameTarget()


def held_base(sim: TechmanSimulator) -> tuple[np.ndarray, Rotation]:
    """The current base as the simulator holds it: position, rotation (R = Rz Ry Rx)."""
    m = matrix(sim.current_base()[1])
    return m[:3, 3], Rotation.from_matrix(m[:3, :3])


def quaternion(rotation: Rotation) -> tuple[float, float, float, float]:
    x, y, z, w = (float(v) for v in rotation.as_quat())
    return w, x, y, z


@pytest.mark.parametrize("seed", range(4))
def test_a_written_base_is_the_current_base_and_nothing_else_changes(
    techman_sim: TechmanSimulator, seed: int
) -> None:
    techman_sim.add_base("Fixture", (100.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    bases, tcp = dict(techman_sim.base_list), techman_sim.current_tcp()
    frame = random_frame(30 + seed)
    with connect(techman_settings(techman_sim)) as tm:
        assert tm.describe_frame(BASE) == "current base"
        tm.write_frame(BASE, frame)
        back = tm.read_frame(BASE)
    position, rotation = held_base(techman_sim)
    assert_allclose(position, frame.position_mm, atol=1e-3)  # held as 32-bit floats
    assert angle_between_deg(quaternion(rotation), frame.quaternion) < 1e-4
    assert techman_sim.current_base()[0] == ""  # set by values: no name of the base list
    assert techman_sim.scripts[-1][1].startswith("ChangeBase({")
    assert techman_sim.scripts[-1][1].endswith("})\r\nQueueTag(15,0)")
    assert techman_sim.base_list == bases
    assert techman_sim.current_tcp() == tcp
    assert_allclose(back.position_mm, frame.position_mm, atol=1e-3)
    assert angle_between_deg(back.quaternion, frame.quaternion) < 1e-4


def test_the_write_waits_for_the_motion_queue(techman_sim: TechmanSimulator) -> None:
    techman_sim.queue_delay_s = 0.3
    with connect(techman_settings(techman_sim)) as tm:
        tm.write_frame(BASE, Frame((0.0, 0.0, 10.0), (1.0, 0.0, 0.0, 0.0)))
        assert tm.read_frame(BASE).position_mm == (0.0, 0.0, 10.0)


def test_a_fixed_tool_has_no_place_and_nothing_is_sent(techman_sim: TechmanSimulator) -> None:
    with connect(techman_settings(techman_sim)) as tm:
        with pytest.raises(ValueError, match="no stationary tool"):
            tm.write_frame(FrameTarget(kind="fixed_tool"), random_frame(1))
        with pytest.raises(ValueError, match="no stationary tool"):
            tm.read_frame(FrameTarget(kind="fixed_tool"))
    assert techman_sim.scripts == []


def test_no_project_running_is_refused_before_anything_is_sent(
    techman_sim: TechmanSimulator,
) -> None:
    techman_sim.stop_project()
    with connect(techman_settings(techman_sim)) as tm:
        assert tm.read_frame(BASE).position_mm == (0.0, 0.0, 0.0)  # reads need no project
        with pytest.raises(ControllerRefused, match="no project is running") as refused:
            tm.write_frame(BASE, random_frame(2))
    assert refused.value.write_sent is False
    assert techman_sim.current_base() == ("RobotBase", (0.0,) * 6)


def test_outside_the_listen_node_the_base_is_refused_saying_what_to_do(
    techman_sim: TechmanSimulator,
) -> None:
    techman_sim.leave_listen_node()
    with connect(techman_settings(techman_sim)) as tm, pytest.raises(ControllerRefused) as refused:
        tm.write_frame(BASE, random_frame(3))
    assert refused.value.write_sent  # sent: only a read tells it was not taken
    assert "$CPERR F1" in refused.value.controller_message
    assert techman_sim.current_base() == ("RobotBase", (0.0,) * 6)


def test_a_project_start_sets_its_own_base_again(techman_sim: TechmanSimulator) -> None:
    """Scope live: the base holds for the running project; a start sets the project's."""
    techman_sim.add_base("Table", (0.0, 500.0, 0.0, 0.0, 0.0, 0.0))
    techman_sim.project_base = "Table"
    with connect(techman_settings(techman_sim)) as tm:
        tm.write_frame(BASE, Frame((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0)))
    techman_sim.start_project()
    with connect(techman_settings(techman_sim)) as tm:
        assert tm.read_frame(BASE).position_mm == (0.0, 500.0, 0.0)


def test_the_live_base_is_base_name_and_base_value(techman_sim: TechmanSimulator) -> None:
    techman_sim.add_base("Fixture", (300.0, 200.0, 50.0, 0.0, 0.0, 30.0))
    techman_sim.select_base("Fixture")
    with connect(techman_settings(techman_sim)) as tm:
        named = tm.read_pose()
        tm.write_frame(BASE, Frame((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0)))
        by_values = tm.read_pose()
    assert named.live_frame.number is None
    assert named.live_frame.name == "Fixture"
    assert named.live_frame.frame is not None
    assert_allclose(named.live_frame.frame.position_mm, (300.0, 200.0, 50.0), atol=1e-4)
    assert named.readings["Base_Name"] == '"Fixture"'
    assert by_values.live_frame.name is None
    assert by_values.live_frame.frame == Frame((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0))


def test_a_data_table_without_the_base_items_leaves_the_live_base_unread(
    techman_sim: TechmanSimulator,
) -> None:
    techman_sim.data_table.discard("Base_Value")
    with connect(techman_settings(techman_sim)) as tm:
        pose = tm.read_pose()  # the pose still reads
        with pytest.raises(ControllerRefused, match="add Base_Value to the Ethernet Slave"):
            tm.read_frame(BASE)
    assert pose.live_frame == UNREAD_FRAME
    assert "Base_Value" not in pose.readings


def test_techmanpy_reads_the_base_the_connector_changed(techman_sim: TechmanSimulator) -> None:
    """techmanpy (PyPI), written apart from this connector, reads Base_Value and Base_Name
    from the Ethernet Slave as the connector's ChangeBase left them."""
    from tests.controllers.test_techman_sim import read_items, run

    with connect(techman_settings(techman_sim)) as tm:
        tm.write_frame(BASE, Frame((612.5, -240.25, 35.125), (0.7071068, 0.0, 0.0, 0.7071068)))
    items = run(read_items(techman_sim, "Base_Value", "Base_Name"))
    assert items["Base_Name"] == ""
    value = items["Base_Value"]
    assert isinstance(value, list)
    assert_allclose(value, [612.5, -240.25, 35.125, 0.0, 0.0, 90.0], atol=1e-4)
