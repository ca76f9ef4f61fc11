"""The KUKAVARPROXY connector against the KRC simulator, and the simulator against
py-openshowvar (a client others wrote from the same protocol)."""

from __future__ import annotations

import socket
import struct
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.vendors.connector import (
    ControllerProtocolError,
    ControllerRefused,
    ControllerSilent,
    ControllerUnreachable,
    ToolTarget,
)
from app.vendors.kuka import kvp
from app.vendors.kuka.kvp import POSE_VARIABLES, KukaKvpConnector
from app.vendors.kuka.text import KrlSyntaxError, parse_struct
from app.vendors.registry import connect
from app.vendors.tool import ToolData, ToolLoad
from tests.controllers.fixtures import kuka_settings
from tests.controllers.helpers import angle_between_deg, float32_tolerance, random_tool
from tests.controllers.kuka_sim import KukaSimulator


def kuka_abc(quaternion_wxyz: tuple[float, ...]) -> np.ndarray:
    """KUKA A, B, C of a quaternion, computed here from scipy's intrinsic Z-Y'-X''."""
    w, x, y, z = quaternion_wxyz
    abc: np.ndarray = Rotation.from_quat([x, y, z, w]).as_euler("ZYX", degrees=True)
    return abc


@pytest.mark.parametrize("seed", range(6))
def test_written_tool_is_held_in_kuka_abc_and_reads_back_to_1e6(seed: int) -> None:
    tool = random_tool(seed)
    assert tool.load is not None
    with KukaSimulator(single_precision=False) as sim, connect(kuka_settings(sim)) as kuka:
        kuka.write_tool(ToolTarget(slot=5), tool)
        held = sim.tool(5)
        assert_allclose(held[:3], tool.position_mm, atol=1e-6)
        assert_allclose(held[3:], kuka_abc(tool.quaternion), atol=1e-6)
        load = sim.load(5)
        assert_allclose(load["M"], tool.load.mass_kg, atol=1e-6)
        assert_allclose(
            [load["CM.X"], load["CM.Y"], load["CM.Z"]], tool.load.cog_or_origin, atol=1e-6
        )
        back = kuka.read_tool(ToolTarget(slot=5))
    assert_allclose(back.position_mm, tool.position_mm, atol=1e-6)
    assert angle_between_deg(back.quaternion, tool.quaternion) < 1e-6
    assert back.load is not None
    assert_allclose(back.load.cog_or_origin, tool.load.cog_or_origin, atol=1e-6)
    assert sim.tool(4) == (0.0,) * 6, "another slot changed"


@pytest.mark.parametrize("seed", range(3))
def test_a_krc_holding_32_bit_reals_reads_back_within_its_resolution(
    kuka_sim: KukaSimulator, seed: int
) -> None:
    tool = random_tool(100 + seed)
    with connect(kuka_settings(kuka_sim)) as kuka:
        kuka.write_tool(ToolTarget(slot=16), tool)
        back = kuka.read_tool(ToolTarget(slot=16))
    held = kuka_sim.tool(16)
    assert_allclose(held[:3], tool.position_mm, atol=float32_tolerance(tool.position_mm))
    assert_allclose(held[3:], kuka_abc(tool.quaternion), atol=float32_tolerance([180.0]))
    assert_allclose(back.position_mm, tool.position_mm, atol=1e-3)
    assert angle_between_deg(back.quaternion, tool.quaternion) < 1e-3


def test_what_the_operator_types_on_the_pendant_is_read(kuka_sim: KukaSimulator) -> None:
    kuka_sim.set_tool(3, 12.5, -4.0, 210.25, 90.0, 0.0, 180.0)
    with connect(kuka_settings(kuka_sim)) as kuka:
        tool = kuka.read_tool(ToolTarget(slot=3))
    assert tool.position_mm == (12.5, -4.0, 210.25)
    # A = 90 about Z then C = 180 about X: x -> y, y -> x, z -> -z.
    expected = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    w, x, y, z = tool.quaternion
    assert_allclose(Rotation.from_quat([x, y, z, w]).as_matrix(), expected, atol=1e-9)
    assert tool.load is None, "M = -1 is the KRC's default load, not a load tcpcal can show"


def test_a_write_without_load_keeps_the_controllers_load_and_inertia(
    kuka_sim: KukaSimulator,
) -> None:
    kuka_sim.set_load(2, 7.5, (1.0, 2.0, 90.0))
    with kuka_sim._data_lock:
        kuka_sim.loads[2]["J.Z"] = 0.25
    with connect(kuka_settings(kuka_sim)) as kuka:
        kuka.write_tool(ToolTarget(slot=2), ToolData((0, 0, 100), (1, 0, 0, 0), None))
        assert kuka.read_tool(ToolTarget(slot=2)).load == ToolLoad(7.5, (1.0, 2.0, 90.0))
        kuka.write_tool(
            ToolTarget(slot=2), ToolData((0, 0, 100), (1, 0, 0, 0), ToolLoad(3.0, (0, 0, 50)))
        )
    assert kuka_sim.load(2)["M"] == 3.0
    assert kuka_sim.load(2)["CM.Z"] == 50.0
    assert kuka_sim.load(2)["J.Z"] == 0.25, "the inertia tcpcal does not know was kept"


def test_an_unknown_variable_or_index_is_refused_with_the_proxys_answer(
    kuka_sim: KukaSimulator,
) -> None:
    with KukaKvpConnector(kuka_settings(kuka_sim)) as kuka:
        with pytest.raises(ControllerRefused) as read_err:
            kuka.read_variable("$TOOL_DATA[17]")
        with pytest.raises(ControllerRefused) as write_err:
            kuka.write_variable("$TOOL_DATA[17]", "{X 1.0}")
        with pytest.raises(ControllerRefused):
            kuka.write_variable("$TOOL_DATA[1]", "{Q 1.0}")
        assert kuka.read_variable("$ROBNAME[]") == '"KR16_R1610_SIM"', "the session survives"
    assert "$TOOL_DATA[17]" in read_err.value.controller_message
    assert "empty value" in read_err.value.controller_message
    assert "write status 0" in write_err.value.controller_message


def test_a_slot_outside_1_16_never_reaches_the_wire(kuka_sim: KukaSimulator) -> None:
    with connect(kuka_settings(kuka_sim)) as kuka, pytest.raises(ValueError, match="1-16"):
        kuka.read_tool(ToolTarget(slot=17))
    assert kuka_sim.requests == []


def test_a_stopped_controller_is_unreachable(kuka_sim: KukaSimulator) -> None:
    settings = kuka_settings(kuka_sim)
    kuka = connect(settings)
    kuka_sim.stop()
    with pytest.raises(ControllerUnreachable):
        kuka.read_tool(ToolTarget(slot=1))
    kuka.close()
    started = time.monotonic()
    with pytest.raises(ControllerUnreachable, match="cannot connect"):
        connect(settings)
    assert time.monotonic() - started < settings.timeout_s


def test_a_controller_that_never_answers_fails_within_the_timeout(kuka_sim: KukaSimulator) -> None:
    kuka_sim.stalled = True
    settings = kuka_settings(kuka_sim, timeout_s=0.5)
    started = time.monotonic()
    silent = pytest.raises(ControllerSilent, match="accepted the TCP connection and sent nothing")
    with silent, connect(settings) as kuka:
        kuka.read_tool(ToolTarget(slot=1))
    elapsed = time.monotonic() - started
    assert elapsed < settings.timeout_s + 1.0, elapsed
    assert elapsed >= settings.timeout_s * 0.9, "it gave up before its timeout"


def test_a_session_that_stalls_after_connecting_fails_within_the_timeout(
    kuka_sim: KukaSimulator,
) -> None:
    settings = kuka_settings(kuka_sim, timeout_s=0.5)
    with connect(settings) as kuka:
        kuka.read_tool(ToolTarget(slot=1))
        kuka_sim.stalled = True
        started = time.monotonic()
        with pytest.raises(ControllerUnreachable, match="did not answer"):
            kuka.write_tool(ToolTarget(slot=1), ToolData((0, 0, 1), (1, 0, 0, 0)))
        assert settings.timeout_s * 0.9 <= time.monotonic() - started < settings.timeout_s + 1


def test_replies_arriving_a_few_bytes_at_a_time_are_put_together(kuka_sim: KukaSimulator) -> None:
    kuka_sim.split_replies = True
    kuka_sim.set_tool(9, 1.0, 2.0, 3.0, 10.0, 20.0, 30.0)
    with connect(kuka_settings(kuka_sim)) as kuka:
        tool = kuka.read_tool(ToolTarget(slot=9))
    assert tool.position_mm == (1.0, 2.0, 3.0)
    assert_allclose(kuka_abc(tool.quaternion), [10.0, 20.0, 30.0], atol=1e-5)


def test_the_simulator_answers_several_requests_sent_in_one_packet(kuka_sim: KukaSimulator) -> None:
    def request(msg_id: int, name: bytes) -> bytes:
        body = b"\x00" + struct.pack("!H", len(name)) + name
        return struct.pack("!HH", msg_id, len(body)) + body

    with socket.create_connection((kuka_sim.host, kuka_sim.port), timeout=2) as sock:
        sock.sendall(request(7, b"PING") + request(8, b"$TOOL_DATA[1]"))
        data = b""
        while data.count(b"\x00\x01\x01") < 2:
            data += sock.recv(4096)
    assert data.startswith(b"\x00\x07\x00\x0a\x00\x00\x04PONG\x00\x01\x01")
    assert data[14:16] == b"\x00\x08", "the second reply, with its own id"
    assert b"{FRAME: X 0.0, Y 0.0, Z 0.0, A 0.0, B 0.0, C 0.0}" in data


def test_py_openshowvar_reads_and_writes_the_simulator(kuka_sim: KukaSimulator) -> None:
    from py_openshowvar import openshowvar

    kuka_sim.set_tool(4, 1.5, 2.5, 300.0, 0.0, 90.0, 0.0)
    client = openshowvar(kuka_sim.host, kuka_sim.port)
    try:
        text = client.read("$TOOL_DATA[4]", debug=False)
        assert text == b"{FRAME: X 1.5, Y 2.5, Z 300.0, A 0.0, B 90.0, C 0.0}"
        assert client.read("$TOOL_DATA[4]", debug=False) == text, "message ids follow on"
        echoed = client.write(
            "$TOOL_DATA[4]", "{X 10.0,Y 20.0,Z 30.0,A 1.0,B 2.0,C 3.0}", debug=False
        )
        assert echoed == b"{X 10.0,Y 20.0,Z 30.0,A 1.0,B 2.0,C 3.0}"
        # py-openshowvar returns None for a reply whose status byte is not 1.
        assert client.write("$TOOL_DATA[99]", "{X 1.0}", debug=False) is None
    finally:
        client.close()
    assert kuka_sim.tool(4) == (10.0, 20.0, 30.0, 1.0, 2.0, 3.0)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("{FRAME: X 0.0,Y -1.5,Z 150.0,A 0.0,B 90.0,C -180.0}", {"X": 0.0, "Y": -1.5, "Z": 150.0}),
        ("{X 1.0, Y 2.0 , Z 3.0,A 0.0,B 0.0,C 0.0}", {"X": 1.0, "Y": 2.0, "Z": 3.0}),
        (
            "  { FRAME :X 1.5E-05,Y 2,Z -3.25E+02,A 0,B 0,C 0 }",
            {"X": 1.5e-5, "Y": 2.0, "Z": -325.0},
        ),
    ],
)
def test_krl_frames_as_the_krc_prints_them(text: str, expected: dict[str, float]) -> None:
    parsed = parse_struct(text)
    for key, value in expected.items():
        assert parsed[key] == value


def test_krl_nested_load_and_refusals() -> None:
    load = parse_struct(
        "{LOAD: M 2.5,CM {FRAME: X 0.0,Y 0.0,Z 80.0,A 0.0,B 0.0,C 0.0},"
        "J {INERTIA: X 0.1,Y 0.2,Z 0.3}}"
    )
    assert load["M"] == 2.5
    assert load["CM"] == {"X": 0.0, "Y": 0.0, "Z": 80.0, "A": 0.0, "B": 0.0, "C": 0.0}
    assert load["J"] == {"X": 0.1, "Y": 0.2, "Z": 0.3}
    assert parse_struct("{E6POS: }") == {}
    for bad in ("", "X 1.0", "{X 1.0", "{X 1.0}}", "{X }", "{,}"):
        with pytest.raises(KrlSyntaxError):
            parse_struct(bad)


def test_the_krc_reads_a_write_as_krl_not_as_python(kuka_sim: KukaSimulator) -> None:
    """The simulator reads a write with its own KRL reader: what KRL accepts changes the
    tool, what only Python's float would take is refused with write status 0 (the
    connector's parser takes ``1_000.0``: a writer sharing it would pass a shared reader)."""
    assert parse_struct("{X 1_000.0}") == {"X": 1000.0}
    with KukaKvpConnector(kuka_settings(kuka_sim)) as kuka:
        kuka.write_variable("$TOOL_DATA[2]", "{FRAME: x 1.5, Y -2.5E+02 ,Z .25}")
        assert kuka_sim.tool(2) == (1.5, -250.0, 0.25, 0.0, 0.0, 0.0)
        for bad in ("{X 1_000.0}", "{X nan}", "{X inf}", "{X 1.0,X 2.0}", "{X 1.0,}", "{X #NONE}"):
            with pytest.raises(ControllerRefused, match="write status 0"):
                kuka.write_variable("$TOOL_DATA[2]", bad)
    assert kuka_sim.tool(2) == (1.5, -250.0, 0.25, 0.0, 0.0, 0.0), "a refused write changed it"


# --- where the robot stands: $POS_ACT, $AXIS_ACT, $TOOL, $BASE, $ACT_TOOL, $IPO_MODE ------------


def wxyz(matrix: np.ndarray) -> tuple[float, float, float, float]:
    """A 3x3 rotation as a quaternion w, x, y, z (scipy)."""
    x, y, z, w = Rotation.from_matrix(matrix).as_quat()
    return float(w), float(x), float(y), float(z)


def test_the_simulators_pos_act_is_the_tcp_of_tool_in_base_worked_by_hand(
    kuka_sim: KukaSimulator,
) -> None:
    """The simulator's own arithmetic, checked against numbers worked out by hand: the
    flange at (1000, 200, 800) turned A = 90 (its x along the robot's y), the tool 100 mm
    along the flange's x, $BASE at (500, 0, 0) turned A = -30. The TCP is then at
    (1000, 300, 800) in the robot's base, (500, 300, 800) from the base's origin, and seen
    in the base turned by +30 deg about z; its orientation is A = 90 + 30."""
    kuka_sim.set_tool(2, 100.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    kuka_sim.select_tool(2)
    kuka_sim.set_base(500.0, 0.0, 0.0, -30.0, 0.0, 0.0)
    kuka_sim.jog_flange(1000.0, 200.0, 800.0, 90.0, 0.0, 0.0)
    cos30, sin30 = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    pos = kuka_sim.pos_act()
    expected = [500 * cos30 - 300 * sin30, 500 * sin30 + 300 * cos30, 800.0, 120.0, 0.0, 0.0]
    assert_allclose([pos[k] for k in "XYZABC"], expected, atol=1e-4)
    kuka_sim.set_joints(10.0, -80.0, 95.0, -5.0, 30.0, -170.0)
    text = kuka_sim.show_var("$POS_ACT")
    assert text is not None
    assert text.startswith("{E6POS: X 283.012")
    # T: bit n set for axis n+1 below zero (A2, A4, A6: 2 + 8 + 32)
    assert text.endswith(", S 2, T 42, E1 0.0, E2 0.0, E3 0.0, E4 0.0, E5 0.0, E6 0.0}")


@pytest.mark.parametrize("seed", range(4))
def test_read_pose_gives_the_simulators_own_flange_to_1e6(seed: int) -> None:
    """A general pose: a tool, a base and the robot's root in $WORLD ($ROBROOT_C) each
    shifted and turned by three unequal angles, the flange anywhere; the connector's flange
    is the one the simulator computed $POS_ACT from, to 1e-6 mm and 1e-6 deg (the simulator
    keeping every digit)."""
    rng = np.random.default_rng(seed)
    tool = (*rng.uniform(-150, 150, 2), rng.uniform(80, 300), 35.0, -20.0, 170.0 - 15 * seed)
    base = (*rng.uniform(-800, 800, 3), -60.0 + seed, 7.5, -12.25)
    robroot = (*rng.uniform(-3000, 3000, 3), 25.0 - 10 * seed, -14.0, 172.5)
    flange_at = rng.uniform(-1200, 1200, 3)
    flange_turn = Rotation.random(random_state=rng).as_matrix()
    joints = tuple(float(v) for v in rng.uniform(-170, 170, 6))
    with KukaSimulator(single_precision=False) as sim:
        sim.set_tool(7, *tool)
        sim.select_tool(7)
        sim.set_base(*base)
        sim.set_robroot(*robroot)
        sim.set_flange(tuple(flange_at), flange_turn)
        sim.set_joints(*joints)
        with KukaKvpConnector(kuka_settings(sim)) as kuka:
            reading = kuka.read_pose()
        shown = {name: sim.show_var(name) for name in POSE_VARIABLES}
        held_at, held_turn = sim.flange()
        pos_act = sim.pos_act()
    assert np.linalg.norm(np.subtract([pos_act[k] for k in "XYZ"], held_at)) > 100, (
        "the tool and base must move the TCP away from the flange, or this test shows nothing"
    )
    assert_allclose(reading.flange.position_mm, held_at, atol=1e-6)
    assert angle_between_deg(reading.flange.quaternion, wxyz(held_turn)) < 1e-6
    assert reading.joints_deg == joints
    assert reading.live_tool.number == 7
    assert reading.live_tool.frame is not None
    assert_allclose(reading.live_tool.frame.position_mm, tool[:3], atol=1e-9)
    assert_allclose(kuka_abc(reading.live_tool.frame.quaternion), tool[3:], atol=1e-9)
    assert reading.readings == shown, "each value as the KRC printed it"
    assert list(reading.readings) == list(POSE_VARIABLES)


@pytest.mark.parametrize(
    ("mount", "robroot"),
    [
        ("on a track, 2.4 m along it", (2400.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        ("on a 400 mm riser, turned 90 deg", (0.0, 0.0, 400.0, 90.0, 0.0, 0.0)),
        ("on the ceiling", (500.0, -300.0, 3200.0, 0.0, 0.0, 180.0)),
        ("on a wall", (0.0, 1500.0, 1200.0, 0.0, 90.0, 0.0)),
    ],
)
def test_the_flange_is_in_the_robots_base_frame_wherever_it_stands_in_world(
    mount: str, robroot: tuple[float, ...]
) -> None:
    """Issue 51: the flange was $BASE * $POS_ACT * inverse($TOOL), the flange in $WORLD,
    right only when $ROBROOT = $WORLD; $BASE (every BASE_DATA) is in $WORLD, and a robot on
    a track or another mount stands at $ROBROOT_C in it. The flange is in the robot's own
    base frame wherever the robot stands: inverse($ROBROOT_C) * $BASE * $POS_ACT * $TOOL^-1."""
    with KukaSimulator(single_precision=False) as sim:
        sim.set_tool(4, 0.0, 0.0, 250.0, 0.0, 30.0, 0.0)
        sim.select_tool(4)
        sim.set_base(1200.0, 800.0, 600.0, -45.0, 0.0, 0.0)  # a BASE_DATA, in $WORLD
        sim.set_robroot(*robroot)
        sim.jog_flange(900.0, -150.0, 1100.0, 10.0, 80.0, -170.0)
        with KukaKvpConnector(kuka_settings(sim)) as kuka:
            reading = kuka.read_pose()
        held_at, held_turn = sim.flange()
    off_mm = float(np.linalg.norm(np.subtract(reading.flange.position_mm, held_at)))
    off_deg = angle_between_deg(reading.flange.quaternion, wxyz(held_turn))
    assert off_mm < 1e-6, (mount, off_mm, off_deg)
    assert off_deg < 1e-6, (mount, off_mm, off_deg)
    assert reading.readings["$ROBROOT_C"] == sim.show_var("$ROBROOT_C")


def test_a_moving_robots_pose_does_not_push_its_tool_and_base_out_of_memory(
    kuka_sim: KukaSimulator,
) -> None:
    """$POS_ACT's angles are converted without being remembered (issue 50: a plant's robots
    move, and each round's new angles filled the remembered conversions and pushed out the
    tools and bases every round reads again); the tools are, and $TOOL, $BASE and $ROBROOT_C
    composed, once (`_standing`)."""
    kuka_sim.set_tool(3, 10.0, -20.0, 180.0, 12.5, -7.25, 3.125)
    kuka_sim.select_tool(3)
    kuka_sim.set_base(400.0, -300.0, 50.0, 33.0, 1.5, -2.5)
    rng = np.random.default_rng(50)
    with KukaKvpConnector(kuka_settings(kuka_sim)) as kuka:
        kuka.read_pose()
        kept = kvp._quaternion.cache_info().currsize
        standing = kvp._standing.cache_info().currsize
        for _ in range(40):
            kuka_sim.jog_flange(*rng.uniform(-900, 900, 3), *rng.uniform(-170, 170, 3))
            reading = kuka.read_pose()
        held_at, held_turn = kuka_sim.flange()
    assert kvp._quaternion.cache_info().currsize == kept, "40 poses, nothing more remembered"
    assert kvp._standing.cache_info().currsize == standing, "one tool and base, kept once"
    assert_allclose(reading.flange.position_mm, held_at, atol=1e-3)
    assert angle_between_deg(reading.flange.quaternion, wxyz(held_turn)) < 1e-3


def test_read_pose_asks_for_the_six_variables_once(kuka_sim: KukaSimulator) -> None:
    with KukaKvpConnector(kuka_settings(kuka_sim)) as kuka:
        kuka.read_pose()
    assert kuka_sim.requests == [(0, name, None) for name in POSE_VARIABLES]


def test_a_tool_set_without_a_number_is_live_with_no_number(kuka_sim: KukaSimulator) -> None:
    kuka_sim.set_tool_frame(0.0, 0.0, 250.0, 0.0, 0.0, 0.0)
    kuka_sim.jog_flange(900.0, 0.0, 600.0, 0.0, 180.0, 0.0)
    with KukaKvpConnector(kuka_settings(kuka_sim)) as kuka:
        reading = kuka.read_pose()
    assert reading.readings["$ACT_TOOL"] == "-1"
    assert reading.live_tool.number is None
    assert reading.live_tool.frame is not None
    assert reading.live_tool.frame.position_mm == (0.0, 0.0, 250.0)
    assert_allclose(reading.flange.position_mm, (900.0, 0.0, 600.0), atol=1e-3)


def test_external_tcp_mode_is_refused_naming_it(kuka_sim: KukaSimulator) -> None:
    kuka_sim.ipo_mode = "#TCP"
    with (
        KukaKvpConnector(kuka_settings(kuka_sim)) as kuka,
        pytest.raises(ControllerRefused, match=r"\$IPO_MODE #TCP") as refused,
    ):
        kuka.read_pose()
    assert refused.value.controller_message == "$IPO_MODE #TCP"
    assert "External TCP off" in str(refused.value), "it says what to do"
    assert "capture again" in str(refused.value)


@pytest.mark.parametrize(
    ("text", "what"),
    [
        ("{E6POS: }", "has no number X"),
        ("{E6POS: X nan, Y 0.0, Z 0.0, A 0.0, B 0.0, C 0.0}", "is not finite"),
    ],
)
def test_a_pos_act_without_six_finite_numbers_is_not_a_pose(
    kuka_sim: KukaSimulator, monkeypatch: pytest.MonkeyPatch, text: str, what: str
) -> None:
    shown = kuka_sim.show_var
    monkeypatch.setattr(
        kuka_sim, "show_var", lambda name: text if name == "$POS_ACT" else shown(name)
    )
    with (
        KukaKvpConnector(kuka_settings(kuka_sim)) as kuka,
        pytest.raises(ControllerProtocolError, match=r"\$POS_ACT") as err,
    ):
        kuka.read_pose()
    assert what in str(err.value)


@pytest.mark.parametrize("when", ["from the start", "after a pose was read"])
def test_a_pose_read_from_a_stalled_krc_fails_within_the_timeout(
    kuka_sim: KukaSimulator, when: str
) -> None:
    settings = kuka_settings(kuka_sim, timeout_s=0.5)
    kuka_sim.stalled = silent = when == "from the start"
    with KukaKvpConnector(settings) as kuka:
        if not kuka_sim.stalled:
            kuka.read_pose()
            kuka_sim.stalled = True
        started = time.monotonic()
        # a KRC that never answered is silent (perhaps not KUKAVARPROXY); one that did stopped
        said = "accepted the TCP connection and sent nothing" if silent else "did not answer"
        with pytest.raises(ControllerUnreachable, match=rf"{said} within 0\.5 s") as raised:
            kuka.read_pose()
        elapsed = time.monotonic() - started
        assert isinstance(raised.value, ControllerSilent) is silent
    assert settings.timeout_s * 0.9 <= elapsed < settings.timeout_s + 1.0, elapsed


def test_py_openshowvar_reads_the_pos_act_the_connector_parses(kuka_sim: KukaSimulator) -> None:
    from py_openshowvar import openshowvar

    kuka_sim.set_tool(5, 12.0, -30.5, 210.0, 15.0, -25.0, 95.0)
    kuka_sim.select_tool(5)
    kuka_sim.set_base(1500.0, -250.0, 40.0, 170.0, 3.0, -1.5)
    kuka_sim.jog_flange(1104.25, -431.5, 622.75, -140.0, 62.0, 178.0)
    kuka_sim.set_joints(-35.5, -70.25, 101.0, 12.0, 48.5, -210.0)
    client = openshowvar(kuka_sim.host, kuka_sim.port)
    try:
        pos_act = client.read("$POS_ACT", debug=False)
        axis_act = client.read("$AXIS_ACT", debug=False)
    finally:
        client.close()
    with KukaKvpConnector(kuka_settings(kuka_sim)) as kuka:
        reading = kuka.read_pose()
    assert pos_act is not None
    assert pos_act.startswith(b"{E6POS: X ")
    assert pos_act.decode() == reading.readings["$POS_ACT"] == kuka_sim.show_var("$POS_ACT")
    assert axis_act == b"{E6AXIS: A1 -35.5, A2 -70.25, A3 101.0, A4 12.0, A5 48.5, A6 -210.0, " + (
        b"E1 0.0, E2 0.0, E3 0.0, E4 0.0, E5 0.0, E6 0.0}"
    )
    held_at, held_turn = kuka_sim.flange()
    # What 32-bit REALs of nine digits leave: well under a micrometre and a millidegree.
    assert_allclose(reading.flange.position_mm, held_at, atol=1e-3)
    assert angle_between_deg(reading.flange.quaternion, wxyz(held_turn)) < 1e-3
