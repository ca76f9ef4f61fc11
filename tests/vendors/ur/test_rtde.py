"""The ur_rtde connector against the UR simulator (tests/controllers/ur_sim.py): the live TCP
written by a secondary program and read back over RTDE, the flange read as
actual_TCP_pose * inverse(tcp_offset), and what each refusal and silence leaves."""

from __future__ import annotations

import socket
import time
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.vendors.connector import ControllerRefused, ControllerUnreachable, ToolTarget
from app.vendors.registry import connect
from app.vendors.tool import ToolData, ToolLoad
from app.vendors.ur import rtde as ur_rtde
from tests.controllers.fixtures import ur_settings
from tests.controllers.helpers import angle_between_deg, random_tool
from tests.controllers.simbase import go_silent
from tests.controllers.ur_sim import UrSimulator

LIVE = ToolTarget()
TIMEOUT_S = 0.5
BAD_PROGRAM = "sec tcpcal_set_tcp():\n  set_tcp(p[0.1, 0.2])\nend\n"


def ur_pose(data: ToolData) -> tuple[float, ...]:
    """The pose the controller should hold for `data`: m and a rotation vector (scipy)."""
    w, x, y, z = data.quaternion
    rotvec = Rotation.from_quat([x, y, z, w]).as_rotvec()
    return (*(v / 1000.0 for v in data.position_mm), *(float(v) for v in rotvec))


def assert_holds(sim: UrSimulator, data: ToolData) -> None:
    held, wanted = sim.tcp(), ur_pose(data)
    assert held[:3] == pytest.approx(wanted[:3], abs=1e-9)  # 1e-6 mm
    off = Rotation.from_rotvec(held[3:]).inv() * Rotation.from_rotvec(wanted[3:])
    assert np.degrees(off.magnitude()) < 1e-6


def _closed(sim: UrSimulator) -> None:
    """Every connection the connector opened is closed (seen by the controller)."""
    deadline = time.monotonic() + 2
    while sim.open_connections() != {"rtde": 0, "secondary": 0} and time.monotonic() < deadline:
        time.sleep(0.01)
    assert sim.open_connections() == {"rtde": 0, "secondary": 0}


@pytest.mark.parametrize("seed", range(5))
def test_write_then_read_back_gives_the_tool_and_its_load(ur_sim: UrSimulator, seed: int) -> None:
    data = random_tool(seed)
    with connect(ur_settings(ur_sim)) as ur:
        assert ur.describe(LIVE) == "tcp_offset"
        ur.write_tool(LIVE, data)
        back = ur.read_tool(LIVE)
    assert_holds(ur_sim, data)
    assert back.position_mm == pytest.approx(data.position_mm, abs=1e-6)
    assert angle_between_deg(back.quaternion, data.quaternion) < 1e-6
    assert data.load is not None
    assert back.load is not None
    assert back.load.mass_kg == pytest.approx(data.load.mass_kg, abs=1e-9)
    assert back.load.cog_mm == pytest.approx(data.load.cog_mm, abs=1e-6)
    # a secondary program: the program the robot runs goes on
    assert [p.kind for p in ur_sim.programs] == ["sec"]
    assert ur_sim.program_running
    _closed(ur_sim)


def test_a_tool_without_a_load_leaves_the_payload(ur_sim: UrSimulator) -> None:
    ur_sim.payload_kg = 3.0
    with connect(ur_settings(ur_sim)) as ur:
        ur.write_tool(LIVE, random_tool(3, load=False))
    assert "set_payload" not in ur_sim.programs[0].text
    assert ur_sim.payload_kg == 3.0


def test_read_pose_is_the_flange_the_joints_and_the_live_tcp(ur_sim: UrSimulator) -> None:
    rotation = Rotation.from_euler("xyz", [170, -5, 30], degrees=True)
    ur_sim.set_flange((412.5, -130.25, 377.0), rotation.as_matrix())
    ur_sim.set_joints(12, -80, 95, -100, -90, 33)
    ur_sim.pendant_set_tcp((0.01, -0.02, 0.18, 0.1, -0.2, 0.3))
    with connect(ur_settings(ur_sim)) as ur:
        reading = ur.read_pose()
    assert reading.flange.position_mm == pytest.approx((412.5, -130.25, 377.0), abs=1e-6)
    w, x, y, z = reading.flange.quaternion
    assert (Rotation.from_quat([x, y, z, w]).inv() * rotation).magnitude() < 1e-9
    assert reading.joints_deg == pytest.approx((12, -80, 95, -100, -90, 33), abs=1e-9)
    assert reading.live_tool.number is None
    assert reading.live_tool.frame is not None
    assert reading.live_tool.frame.position_mm == pytest.approx((10.0, -20.0, 180.0), abs=1e-9)
    assert set(reading.readings) == {"actual_TCP_pose", "tcp_offset", "actual_q", "timestamp"}
    assert reading.readings["tcp_offset"] == "[0.01, -0.02, 0.18, 0.1, -0.2, 0.3]"


def test_a_protective_stop_refuses_before_anything_is_sent(ur_sim: UrSimulator) -> None:
    ur_sim.protective_stop()
    with pytest.raises(ControllerRefused) as caught, connect(ur_settings(ur_sim)) as ur:
        ur.write_tool(LIVE, random_tool(1))
    assert caught.value.write_sent is False
    assert "safety_mode 3 (protective stop)" in caught.value.controller_message
    assert "release the stop" in str(caught.value)
    assert ur_sim.programs == []
    _closed(ur_sim)


def test_local_control_is_refused_with_c210_and_the_tcp_is_kept(ur_sim: UrSimulator) -> None:
    ur_sim.remote_control(False)
    before = ur_sim.tcp()
    with pytest.raises(ControllerRefused) as caught, connect(ur_settings(ur_sim)) as ur:
        ur.write_tool(LIVE, random_tool(2))
    assert caught.value.write_sent is True  # the program left; the controller ignored it
    assert caught.value.controller_message.startswith("C210A0")
    assert "Remote Control" in str(caught.value)
    assert ur_sim.tcp() == before
    _closed(ur_sim)


def test_a_program_the_controller_stops_is_refused_with_its_line(
    ur_sim: UrSimulator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A runtime exception on the secondary interface is a refusal in the controller's
    words (the program here is planted: the connector writes only finite poses)."""
    monkeypatch.setattr(ur_rtde, "set_tcp_program", lambda _data: BAD_PROGRAM)
    before = ur_sim.tcp()
    with pytest.raises(ControllerRefused) as caught, connect(ur_settings(ur_sim)) as ur:
        ur.write_tool(LIVE, random_tool(4))
    assert caught.value.write_sent is True
    assert caught.value.controller_message.startswith("line 2, column 1: set_tcp needs a pose")
    assert ur_sim.tcp() == before


@pytest.mark.parametrize("moment", ["before", "after"])
def test_silence_after_the_program_is_sent_is_unreachable_and_write_sent(
    ur_sim: UrSimulator, moment: str
) -> None:
    ur_sim.fault = go_silent(moment, "script")  # type: ignore[arg-type]
    started = time.monotonic()
    with (
        pytest.raises(ControllerUnreachable, match="did not answer") as caught,
        connect(ur_settings(ur_sim, timeout_s=TIMEOUT_S)) as ur,
    ):
        ur.write_tool(LIVE, random_tool(5))
    assert caught.value.write_sent is True
    assert ur_sim.stalled
    assert time.monotonic() - started < TIMEOUT_S + 1
    _closed(ur_sim)


@pytest.mark.parametrize(
    "stage",
    [
        "RTDE_REQUEST_PROTOCOL_VERSION",
        "RTDE_CONTROL_PACKAGE_SETUP_OUTPUTS",
        "RTDE_CONTROL_PACKAGE_START",
    ],
)
def test_silence_before_the_write_leaves_the_mark_off(ur_sim: UrSimulator, stage: str) -> None:
    ur_sim.fault = go_silent("before", stage)
    with (
        pytest.raises(ControllerUnreachable) as caught,
        connect(ur_settings(ur_sim, timeout_s=TIMEOUT_S)) as ur,
    ):
        ur.write_tool(LIVE, random_tool(6))
    assert caught.value.write_sent is False
    assert ur_sim.programs == []


def test_a_silent_secondary_interface_fails_before_the_write(ur_sim: UrSimulator) -> None:
    """A secondary port that accepts and says nothing (not even the version message a
    controller sends on connection): nothing is sent, so nothing was written."""
    with socket.socket() as quiet:
        quiet.bind(("127.0.0.1", 0))
        quiet.listen(1)
        ports = {"rtde": ur_sim.rtde_port, "secondary": quiet.getsockname()[1]}
        settings = replace(ur_settings(ur_sim, timeout_s=TIMEOUT_S), ports=ports)
        with pytest.raises(ControllerUnreachable) as caught, connect(settings) as ur:
            ur.write_tool(LIVE, random_tool(6))
    assert caught.value.write_sent is False
    assert ur_sim.programs == []


def test_an_old_polyscope_without_tcp_offset_is_refused_saying_what_to_update() -> None:
    with UrSimulator(version=(5, 4, 3, 0)) as old:
        with pytest.raises(ControllerRefused) as caught:
            connect(ur_settings(old))
        assert "tcp_offset" in str(caught.value)
        assert "5.5.1" in str(caught.value)
        _closed(old)


def test_a_session_left_behind_does_not_stop_the_next(ur_sim: UrSimulator) -> None:
    """A client that set up RTDE inputs and never closed holds them: tcpcal reads outputs
    only, and its own failed sessions close both connections."""
    ur_sim.hold_inputs("input_double_register_0", "speed_slider_fraction")
    data = random_tool(8)
    with connect(ur_settings(ur_sim)) as ur:
        ur.write_tool(LIVE, data)
    assert_holds(ur_sim, data)
    _closed(ur_sim)


def test_a_program_start_brings_the_installation_tcp_back(ur_sim: UrSimulator) -> None:
    """Live only: the next program start sets the installation's TCP, and a read says so."""
    ur_sim.pendant_set_tcp((0.0, 0.0, 0.1, 0.0, 0.0, 0.0))
    data = random_tool(9)
    with connect(ur_settings(ur_sim)) as ur:
        ur.write_tool(LIVE, data)
    ur_sim.play_program()
    with connect(ur_settings(ur_sim)) as ur:
        back = ur.read_tool(LIVE)
    assert back.position_mm == pytest.approx((0.0, 0.0, 100.0), abs=1e-9)


def test_the_program_sets_the_payload_in_kg_and_m(ur_sim: UrSimulator) -> None:
    data = ToolData(
        position_mm=(1.0, 2.0, 150.0),
        quaternion=(1.0, 0.0, 0.0, 0.0),
        load=ToolLoad(mass_kg=2.5, cog_mm=(0.0, 10.0, 80.0)),
    )
    with connect(ur_settings(ur_sim)) as ur:
        ur.write_tool(LIVE, data)
    assert ur_sim.payload_kg == 2.5
    assert ur_sim.payload_cog_m == pytest.approx((0.0, 0.01, 0.08))
    assert ur_sim.tcp() == pytest.approx((0.001, 0.002, 0.15, 0.0, 0.0, 0.0))
