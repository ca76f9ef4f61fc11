"""The Yaskawa HSES connector against the HSES simulator (tests/controllers/yaskawa_sim.py,
written from the HSES manuals; it parses and prints TOOL.CND itself): a tool written into
its TOOL.CND block and read back, every other byte of the file kept, a refused load reported
in the controller's words with nothing changed, a transfer left behind waited out within the
deadline, and the pose read as the position read times the inverse of the reported tool."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.vendors.connector import ControllerRefused, ControllerUnreachable, ToolTarget
from app.vendors.registry import connect
from app.vendors.tool import ToolData, ToolLoad
from app.vendors.yaskawa.hses import YaskawaHsesConnector
from app.vendors.yaskawa.hses_wire import status_text
from tests.controllers.fixtures import yaskawa_settings
from tests.controllers.helpers import angle_between_deg, random_tool
from tests.controllers.yaskawa_sim import TOOLS, YaskawaSimulator


def yaskawa_rotation(rx: float, ry: float, rz: float) -> Rotation:
    """R = Rz·Ry·Rx about the fixed axes (deg), composed from single-axis rotations as
    Yaskawa-Global/motoros2 composes Rx Ry Rz (not taken from app.kinematics)."""
    return (
        Rotation.from_euler("z", rz, degrees=True)
        * Rotation.from_euler("y", ry, degrees=True)
        * Rotation.from_euler("x", rx, degrees=True)
    )


def rotation_of(quaternion_wxyz: tuple[float, ...]) -> Rotation:
    w, x, y, z = quaternion_wxyz
    return Rotation.from_quat([x, y, z, w])


def blocks(cnd: bytes) -> dict[int, bytes]:
    """TOOL.CND's blocks by tool number, each as saved (its bytes up to the next)."""
    starts = [cnd.index(f"//TOOL {n}\r\n".encode()) for n in TOOLS] + [len(cnd)]
    return {n: cnd[starts[n] : starts[n + 1]] for n in TOOLS}


@pytest.mark.parametrize("slot", [0, 5, 63])
def test_a_written_tool_is_held_at_the_files_resolution_and_reads_back(
    yaskawa_sim: YaskawaSimulator, slot: int
) -> None:
    tool = random_tool(slot)
    with connect(yaskawa_settings(yaskawa_sim)) as yaskawa:
        assert isinstance(yaskawa, YaskawaHsesConnector)
        assert yaskawa.describe(ToolTarget(slot=slot)) == f"TOOL.CND tool {slot}"
        yaskawa.write_tool(ToolTarget(slot=slot), tool)
        back = yaskawa.read_tool(ToolTarget(slot=slot))
    position, angles = yaskawa_sim.tool(slot)
    assert_allclose(position, tool.position_mm, atol=0.0005)  # 3 decimals of mm
    held = yaskawa_rotation(*angles)
    assert np.degrees((held.inv() * rotation_of(tool.quaternion)).magnitude()) < 2e-4
    assert_allclose(back.position_mm, tool.position_mm, atol=0.001)
    assert angle_between_deg(back.quaternion, tool.quaternion) < 0.001
    assert tool.load is not None
    assert yaskawa_sim.tools[slot].mass == round(tool.load.mass_kg * 1000)
    assert yaskawa_sim.tools[slot].cog == tuple(round(c * 1000) for c in tool.load.cog_or_origin)
    assert back.load is not None
    assert back.load.mass_kg == pytest.approx(tool.load.mass_kg, abs=0.0005)


def test_every_other_byte_of_tool_cnd_stays_the_controllers(yaskawa_sim: YaskawaSimulator) -> None:
    """Only the tool's X Y Z Rx Ry Rz line changes when tcpcal has no load for it: the other
    63 blocks, the block's name, CRC, load, inertia and last lines stay byte for byte."""
    for n in (0, 6, 7, 8, 40, 63):
        yaskawa_sim.set_tool(
            n,
            (n + 0.5, -n, 2.0 * n),
            (n / 3, -n / 7, n),
            name=f"T{n}",
            mass_kg=n / 10 + 1,
            cog_mm=(1.0, 2.0, float(n)),
        )
    before = blocks(yaskawa_sim.tool_cnd())
    w, x, y, z = _wxyz(10.0, -30.0, 45.0)
    tool = ToolData((12.5, -4.25, 215.25), (w, x, y, z))
    with connect(yaskawa_settings(yaskawa_sim)) as yaskawa:
        yaskawa.write_tool(ToolTarget(slot=7), tool)
    after = blocks(yaskawa_sim.tool_cnd())
    assert yaskawa_sim.loads_applied == 1
    assert {n: after[n] for n in TOOLS if n != 7} == {n: before[n] for n in TOOLS if n != 7}
    old, new = before[7].split(b"\r\n"), after[7].split(b"\r\n")
    changed = [i for i, (a, b) in enumerate(zip(old, new, strict=True)) if a != b]
    assert changed == [3], (old, new)  # //TOOL, ///CRC, ///NAME, then the pose line
    assert new[3] == b"12.500,-4.250,215.250,10.0000,-30.0000,45.0000"


def _wxyz(rx: float, ry: float, rz: float) -> list[float]:
    x, y, z, w = (float(v) for v in yaskawa_rotation(rx, ry, rz).as_quat())
    return [w, x, y, z]


@pytest.mark.parametrize(
    ("pendant", "words", "remedy"),
    [
        ({"mode": "teach"}, "added status 0x2080: incorrect mode", "mode key to REMOTE"),
        ({"remote": False}, "0xE2B2: a file was sent or requested while remote is OFF", "RS005"),
        ({"file_busy": True}, "0x2090: the file is being accessed by another function", "close"),
    ],
    ids=["teach-mode", "remote-off", "file-in-use"],
)
def test_a_refused_load_is_told_in_the_controllers_words_and_changes_nothing(
    yaskawa_sim: YaskawaSimulator, pendant: dict[str, object], words: str, remedy: str
) -> None:
    before = yaskawa_sim.tool_cnd()
    for key, value in pendant.items():
        setattr(yaskawa_sim, key, value)
    with (
        pytest.raises(ControllerRefused) as refused,
        connect(yaskawa_settings(yaskawa_sim)) as yaskawa,
    ):
        yaskawa.write_tool(ToolTarget(slot=3), random_tool(3))
    assert words in refused.value.controller_message
    assert refused.value.controller_message.startswith("status 0x1F, added status 0x")
    assert "refused the load of TOOL.CND" in str(refused.value)
    assert refused.value.remedy is not None
    assert remedy in refused.value.remedy
    assert refused.value.write_sent is False, "refused at the request: no block left"
    assert yaskawa_sim.tool_cnd() == before
    assert yaskawa_sim.loads_applied == 0


def test_a_transfer_left_behind_is_waited_out_within_the_deadline(
    yaskawa_sim: YaskawaSimulator,
) -> None:
    """Another client (or a failed attempt) began a save and went away: the controller
    answers busy (E444) until it drops the transfer, and the connector asks again."""
    yaskawa_sim.leave_transfer_open()
    started = time.monotonic()
    with connect(yaskawa_settings(yaskawa_sim, timeout_s=2.0)) as yaskawa:
        yaskawa.write_tool(ToolTarget(slot=9), random_tool(9))
        back = yaskawa.read_tool(ToolTarget(slot=9))
    elapsed = time.monotonic() - started
    assert yaskawa_sim.transfer_timeout_s - 0.05 <= elapsed < 1.5, elapsed
    assert yaskawa_sim.transfers_timed_out == 1
    assert_allclose(back.position_mm, random_tool(9).position_mm, atol=0.001)


def test_a_transfer_left_behind_past_the_deadline_is_refused_as_busy(
    yaskawa_sim: YaskawaSimulator,
) -> None:
    before = yaskawa_sim.tool_cnd()
    yaskawa_sim.transfer_timeout_s = 5.0
    yaskawa_sim.leave_transfer_open("load")
    started = time.monotonic()
    with (
        pytest.raises(ControllerRefused) as refused,
        connect(yaskawa_settings(yaskawa_sim, timeout_s=0.4)) as yaskawa,
    ):
        yaskawa.write_tool(ToolTarget(slot=9), random_tool(9))
    assert time.monotonic() - started < 0.4 + 0.3
    assert "0xE444: processing another command (busy)" in refused.value.controller_message
    assert refused.value.remedy is not None
    assert "deploy again shortly" in refused.value.remedy
    assert yaskawa_sim.tool_cnd() == before


@pytest.mark.parametrize("fault", ["stalled", "stopped"])
def test_a_silent_or_switched_off_controller_fails_within_the_timeout(
    yaskawa_sim: YaskawaSimulator, fault: str
) -> None:
    settings = yaskawa_settings(yaskawa_sim, timeout_s=0.5)
    if fault == "stalled":
        yaskawa_sim.stalled = True
    else:
        yaskawa_sim.stop()  # a closed port: ICMP port unreachable, waited out like silence
    # connect runs in a thread given 3 s: one that never gives up fails here, not never (the
    # suite has no per-test timeout)
    outcome: list[BaseException | None] = []

    def attempt() -> None:
        try:
            connect(settings).close()
            outcome.append(None)
        except ControllerUnreachable as err:
            outcome.append(err)

    started = time.monotonic()
    thread = threading.Thread(target=attempt, daemon=True)
    thread.start()
    thread.join(3.0)
    took = time.monotonic() - started
    assert outcome, f"connect had not returned after {took:.1f} s (a 0.5 s timeout)"
    assert isinstance(outcome[0], ControllerUnreachable), "a silent controller was connected"
    assert "did not answer" in str(outcome[0])
    assert 0.45 <= took < 0.5 + 0.3


def test_the_pose_is_the_position_read_times_the_inverse_of_the_reported_tool(
    yaskawa_sim: YaskawaSimulator,
) -> None:
    yaskawa_sim.set_tool(4, (12.0, -6.5, 171.25), (20.0, -10.0, 5.0), name="PIN")
    yaskawa_sim.select_tool(4)
    yaskawa_sim.form = 0b101
    flange = np.eye(4)
    flange[:3, :3] = yaskawa_rotation(170.0, 5.0, -20.0).as_matrix()
    flange[:3, 3] = (812.4, -120.7, 433.9)
    yaskawa_sim.set_flange(flange)
    with connect(yaskawa_settings(yaskawa_sim)) as yaskawa:
        reading = yaskawa.read_pose()
    assert_allclose(reading.flange.position_mm, flange[:3, 3], atol=0.002)  # µm reads
    turned = rotation_of(reading.flange.quaternion).inv() * Rotation.from_matrix(flange[:3, :3])
    assert np.degrees(turned.magnitude()) < 2e-4
    assert reading.joints_deg is None, "pulses only: HSES serves no pulse-per-degree"
    assert reading.live_tool.number == 4
    assert reading.live_tool.frame is not None
    assert_allclose(reading.live_tool.frame.position_mm, (12.0, -6.5, 171.25))
    assert reading.readings["TOOL.CND //TOOL 4"] == "12.000,-6.500,171.250,20.0000,-10.0000,5.0000"
    assert reading.readings["0x75 R1 cartesian (base)"].startswith("type 16 form 5 tool 4 user 0")


def test_the_live_tool_is_whichever_the_controller_reports(yaskawa_sim: YaskawaSimulator) -> None:
    with connect(yaskawa_settings(yaskawa_sim)) as yaskawa:
        at_zero = yaskawa.read_pose()
        yaskawa_sim.set_tool(11, (0.0, 0.0, 100.0), (0.0, 0.0, 0.0))
        yaskawa_sim.select_tool(11)
        at_eleven = yaskawa.read_pose()
    assert at_zero.live_tool.number == 0
    assert at_eleven.live_tool.number == 11
    # the same flange, whichever tool the robot moves by
    assert_allclose(at_zero.flange.position_mm, at_eleven.flange.position_mm, atol=0.002)


def test_a_tool_without_a_load_keeps_the_controllers(yaskawa_sim: YaskawaSimulator) -> None:
    yaskawa_sim.set_tool(2, (0.0, 0.0, 50.0), (0.0, 0.0, 0.0), mass_kg=3.25, cog_mm=(1, 2, 3))
    data = ToolData((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0), load=None)
    with connect(yaskawa_settings(yaskawa_sim)) as yaskawa:
        yaskawa.write_tool(ToolTarget(slot=2), data)
        back = yaskawa.read_tool(ToolTarget(slot=2))
    assert back.load == ToolLoad(3.25, (1.0, 2.0, 3.0))
    assert back.position_mm == (1.0, 2.0, 3.0)


def test_the_codes_are_told_in_the_manuals_words() -> None:
    assert status_text(0x1F, 0xE2B2) == (
        "status 0x1F, added status 0xE2B2: a file was sent or requested while remote is OFF"
    )
    assert status_text(0x28, None) == (
        "status 0x28: the instance of the requested data does not exist"
    )
    assert "not in the HSES manual's added status table" in status_text(0x1F, 0x1234)
