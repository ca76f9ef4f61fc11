"""FANUC user frames over RMI against the simulator: FRC_WriteUFrameData and
FRC_ReadUFrameData (B-84184EN 2.3.8, 2.3.9), the active UFRAME of the pose read and refusals
(cuts are tests/vendors/test_frame_cuts.py's)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.vendors.connector import ControllerRefused, Frame, FrameTarget
from app.vendors.registry import connect
from tests.controllers.fanuc_sim import FanucSimulator
from tests.controllers.fixtures import fanuc_settings
from tests.controllers.helpers import angle_between_deg, frame_number_refusal, random_frame
from tests.polling import wait_for

UFRAME_4 = FrameTarget(slot=4)


def fanuc_wpr(quaternion_wxyz: tuple[float, ...]) -> np.ndarray:
    """W, P, R of a quaternion: R = Rz(R) Ry(P) Rx(W), scipy's extrinsic "xyz"."""
    w, x, y, z = quaternion_wxyz
    wpr: np.ndarray = Rotation.from_quat([x, y, z, w]).as_euler("xyz", degrees=True)
    return wpr


def table(sim: FanucSimulator) -> tuple[dict[int, dict[str, float]], ...]:
    return {n: dict(v) for n, v in sim.uframes.items()}, {n: dict(v) for n, v in sim.tools.items()}


@pytest.mark.parametrize("seed", range(4))
def test_a_written_user_frame_is_held_in_wpr_and_every_other_frame_is_untouched(
    seed: int,
) -> None:
    frame = random_frame(10 + seed)
    with FanucSimulator(single_precision=False) as sim:
        sim.set_uframe(9, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
        uframes, tools = table(sim)
        with connect(fanuc_settings(sim)) as fanuc:
            assert fanuc.describe_frame(UFRAME_4) == "UFRAME[4]"
            fanuc.write_frame(UFRAME_4, frame)
            back = fanuc.read_frame(UFRAME_4)
        held = sim.uframe(4)
        after_uframes, after_tools = table(sim)
    assert_allclose(held[:3], frame.position_mm, atol=1e-6)
    assert_allclose(held[3:], fanuc_wpr(frame.quaternion), atol=1e-6)
    assert_allclose(back.position_mm, frame.position_mm, atol=1e-6)
    assert angle_between_deg(back.quaternion, frame.quaternion) < 1e-6
    del uframes[4], after_uframes[4]
    assert after_uframes == uframes
    assert after_tools == tools


def test_a_fixed_tool_is_a_user_frame_too(fanuc_sim: FanucSimulator) -> None:
    with connect(fanuc_settings(fanuc_sim)) as fanuc:
        fanuc.write_frame(
            FrameTarget(kind="fixed_tool", slot=9), Frame((750.0, 0.0, 300.0), (0, 1, 0, 0))
        )
    assert fanuc_sim.uframe(9) == (750.0, 0.0, 300.0, 180.0, 0.0, 0.0)


def test_a_frame_number_outside_1_to_9_never_reaches_the_wire(fanuc_sim: FanucSimulator) -> None:
    with connect(fanuc_settings(fanuc_sim)) as fanuc:
        fanuc_sim.packets.clear()
        for slot in (0, 10, None):
            refusal = frame_number_refusal(slot, "fanuc_rmi", (1, 9), "UFRAME[1..9]")
            with pytest.raises(ValueError, match=refusal):
                fanuc.write_frame(FrameTarget(slot=slot), random_frame(1))
            with pytest.raises(ValueError, match=refusal):
                fanuc.read_frame(FrameTarget(slot=slot))
        assert fanuc_sim.packets == []


def test_a_write_while_the_robot_moves_is_refused_saying_to_wait(
    fanuc_sim: FanucSimulator,
) -> None:
    fanuc_sim.set_uframe(4, 10.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    fanuc_sim.in_motion = True
    with (
        connect(fanuc_settings(fanuc_sim)) as fanuc,
        pytest.raises(ControllerRefused, match="stands still") as refused,
    ):
        fanuc.write_frame(UFRAME_4, Frame((99.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)))
    assert refused.value.controller_message.startswith("RMIT-014")
    assert fanuc_sim.uframe(4)[0] == 10.0


def test_another_group_is_a_refusal_in_the_controllers_words(fanuc_sim: FanucSimulator) -> None:
    """The simulator's RMIT-039 for another group, asked by hand through the connector's
    exchange: the connector itself always names group 1."""
    with (
        connect(fanuc_settings(fanuc_sim)) as fanuc,
        pytest.raises(ControllerRefused, match="RMIT-039 Invalid Group Number"),
    ):
        fanuc._request(  # type: ignore[attr-defined]
            {"Command": "FRC_ReadUFrameData", "FrameNumber": 4, "Group": 2},
            fanuc._deadline,  # type: ignore[attr-defined]
        )


def test_the_live_frame_is_the_active_uframe_as_frc_get_uframe_utool_says(
    fanuc_sim: FanucSimulator,
) -> None:
    fanuc_sim.set_uframe(3, 500.0, -100.0, 20.0, 0.0, 0.0, 90.0)
    fanuc_sim.select(uframe=3, utool=1)
    with connect(fanuc_settings(fanuc_sim)) as fanuc:
        live = fanuc.read_pose().live_frame
        numbers = fanuc._request(  # type: ignore[attr-defined]
            {"Command": "FRC_GetUFrameUTool", "Group": 1},
            fanuc._deadline,  # type: ignore[attr-defined]
        )
        fanuc_sim.select(uframe=0, utool=1)
        world = fanuc.read_pose().live_frame
    assert numbers["UFrameNumber"] == live.number == 3
    assert live.frame is not None
    assert_allclose(live.frame.position_mm, (500.0, -100.0, 20.0), atol=1e-3)
    assert world.number is None
    assert world.frame == Frame((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))


def test_a_session_left_holding_rmi_move_stops_no_frame_write(fanuc_sim: FanucSimulator) -> None:
    fanuc_sim.rmi_move_held = True  # what a motion session that died without FRC_Abort leaves
    with connect(fanuc_settings(fanuc_sim)) as fanuc:
        fanuc.write_frame(UFRAME_4, Frame((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0)))
        assert fanuc.read_frame(UFRAME_4).position_mm == (1.0, 2.0, 3.0)


def test_fanuc_rmi_reads_the_user_frame_the_connector_wrote(fanuc_sim: FanucSimulator) -> None:
    """fanuc-rmi's RobotClient (PyPI), written apart from this connector, reads UFRAME[6]
    and the active frame numbers as the connector left and read them."""
    from tests.controllers.test_fanuc_sim import rmi

    fanuc_sim.select(uframe=6, utool=1)
    with connect(fanuc_settings(fanuc_sim)) as fanuc:
        fanuc.write_frame(
            FrameTarget(slot=6), Frame((1250.5, -310.25, 80.125), (0.0, 0.0, 0.0, 1.0))
        )
        live = fanuc.read_pose().live_frame
    wait_for(lambda: not fanuc_sim.session_open, timeout=10, what="the session to close")
    with rmi(fanuc_sim) as client:
        frame = client.read_uframe_data(6)
        numbers = client.get_uframe_utool()
    assert frame == {"X": 1250.5, "Y": -310.25, "Z": 80.125, "W": 0.0, "P": 0.0, "R": 180.0}
    assert numbers["UFrameNumber"] == live.number == 6
