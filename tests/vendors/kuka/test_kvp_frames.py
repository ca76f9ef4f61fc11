"""KUKA bases through KUKAVARPROXY against the KRC simulator: BASE_DATA[n], BASE_TYPE[n],
BASE_NAME[n,] and the base the robot moves in ($ACT_BASE, $BASE); cuts are
tests/vendors/test_frame_cuts.py's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.vendors.connector import (
    ControllerRefused,
    Frame,
    FrameTarget,
)
from app.vendors.registry import connect
from tests.controllers import kuka_sim as kuka_sim_module
from tests.controllers.fixtures import kuka_settings
from tests.controllers.helpers import angle_between_deg, frame_number_refusal, random_frame
from tests.controllers.kuka_sim import KukaSimulator

BASE_3 = FrameTarget(kind="base", slot=3, name="Fixture A")


def kuka_abc(quaternion_wxyz: tuple[float, ...]) -> np.ndarray:
    """KUKA A, B, C of a quaternion, computed here from scipy's intrinsic Z-Y'-X''."""
    w, x, y, z = quaternion_wxyz
    abc: np.ndarray = Rotation.from_quat([x, y, z, w]).as_euler("ZYX", degrees=True)
    return abc


def table(sim: KukaSimulator) -> tuple[object, ...]:
    """Everything the KRC holds of bases and tools, to compare before and after."""
    return (
        {n: dict(v) for n, v in sim.bases.items()},
        dict(sim.base_names),
        dict(sim.base_types),
        {n: dict(v) for n, v in sim.tools.items()},
    )


@pytest.mark.parametrize("seed", range(4))
def test_a_written_base_is_held_in_kuka_abc_and_every_other_frame_is_untouched(
    seed: int,
) -> None:
    frame = random_frame(seed)
    with KukaSimulator(single_precision=False) as sim:
        sim.set_base_data(7, 10.0, 20.0, 30.0, 40.0, 0.0, 0.0)
        bases, names, types, tools = table(sim)
        with connect(kuka_settings(sim)) as kuka:
            assert kuka.describe_frame(BASE_3) == "BASE_DATA[3]"
            kuka.write_frame(BASE_3, frame)
            back = kuka.read_frame(BASE_3)
        held = sim.base_data(3)
        assert_allclose(held[:3], frame.position_mm, atol=1e-6)
        assert_allclose(held[3:], kuka_abc(frame.quaternion), atol=1e-6)
        assert sim.base_types[3] == "#BASE"
        assert sim.base_names[3] == "Fixture A"
        after = table(sim)
    assert_allclose(back.position_mm, frame.position_mm, atol=1e-6)
    assert angle_between_deg(back.quaternion, frame.quaternion) < 1e-6
    for before, now in zip((bases, names, types), after[:3], strict=True):
        assert {n: v for n, v in now.items() if n != 3} == {  # type: ignore[attr-defined]
            n: v
            for n, v in before.items()  # type: ignore[attr-defined]
            if n != 3
        }
    assert after[3] == tools, "a tool changed"


def test_a_fixed_tool_is_a_base_of_type_tcp_and_its_name_is_cut_to_24_characters(
    kuka_sim: KukaSimulator,
) -> None:
    target = FrameTarget(kind="fixed_tool", slot=12, name='Glue "nozzle" on the stand, left')
    with connect(kuka_settings(kuka_sim)) as kuka:
        kuka.write_frame(target, Frame((800.0, -150.0, 420.0), (0.0, 1.0, 0.0, 0.0)))
    assert kuka_sim.base_types[12] == "#TCP"
    assert kuka_sim.base_names[12] == "Glue nozzle on the stand"
    assert kuka_sim.base_data(12) == (800.0, -150.0, 420.0, 0.0, 0.0, 180.0)


def test_without_a_name_the_krcs_name_is_kept(kuka_sim: KukaSimulator) -> None:
    kuka_sim.base_names[3] = "TABLE"
    with connect(kuka_settings(kuka_sim)) as kuka:
        kuka.write_frame(FrameTarget(slot=3), Frame((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0)))
    assert kuka_sim.base_names[3] == "TABLE"
    assert ("write", "BASE_NAME[3,]") not in {
        ("write" if mode == 1 else "read", name) for mode, name, _ in kuka_sim.requests
    }


def test_a_frame_in_the_robots_base_frame_is_written_into_world_through_robroot() -> None:
    """tcpcal's frame is in the robot's base frame; BASE_DATA is in $WORLD, where the robot
    stands at $ROBROOT_C: BASE_DATA = $ROBROOT_C * frame, and the read undoes it."""
    frame = Frame((500.0, 100.0, -50.0), (0.9238795, 0.0, 0.0, 0.3826834))
    with KukaSimulator(single_precision=False) as sim:
        sim.set_robroot(2400.0, 0.0, 0.0, 90.0, 0.0, 0.0)  # on a track, turned 90 deg
        with connect(kuka_settings(sim)) as kuka:
            kuka.write_frame(BASE_3, frame)
            back = kuka.read_frame(BASE_3)
        held = sim.base_data(3)
    # 90 deg about Z at x 2400: (500, 100) -> (2400 - 100, 500); A 45 + 90
    assert_allclose(held, (2300.0, 500.0, -50.0, 135.0, 0.0, 0.0), atol=1e-5)
    assert_allclose(back.position_mm, frame.position_mm, atol=1e-6)
    assert angle_between_deg(back.quaternion, frame.quaternion) < 1e-6


def test_a_frame_number_outside_1_to_32_is_refused_before_anything_is_sent(
    kuka_sim: KukaSimulator,
) -> None:
    with connect(kuka_settings(kuka_sim)) as kuka:
        for slot in (0, 33, None):
            refusal = frame_number_refusal(slot, "kuka_kvp", (1, 32), "BASE_DATA[1..32]")
            with pytest.raises(ValueError, match=refusal):
                kuka.write_frame(FrameTarget(slot=slot), random_frame(1))
            with pytest.raises(ValueError, match=refusal):
                kuka.read_frame(FrameTarget(slot=slot))
    assert kuka_sim.requests == []


def test_a_base_the_krc_does_not_declare_is_refused_naming_what_to_check(
    kuka_sim: KukaSimulator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A KRC whose $config.dat declares 16 bases answers BASE_DATA[20] empty and refuses
    its write (ok = 0): nothing of the table changes."""
    monkeypatch.setattr(kuka_sim_module, "BASES", range(1, 17))
    before = table(kuka_sim)
    with connect(kuka_settings(kuka_sim)) as kuka:
        with pytest.raises(ControllerRefused, match=r"BASE_DATA\[20\].*base number"):
            kuka.read_frame(FrameTarget(slot=20))
        with pytest.raises(ControllerRefused, match=r"refused to set BASE_DATA\[20\]") as refused:
            kuka.write_frame(FrameTarget(slot=20), random_frame(2))
    assert refused.value.write_sent is True  # refused, but only a read can tell
    assert table(kuka_sim) == before


def test_the_live_base_is_act_base_and_base_in_the_robots_base_frame(
    kuka_sim: KukaSimulator,
) -> None:
    kuka_sim.set_base_data(5, 1000.0, 200.0, 300.0, 30.0, 0.0, 0.0)
    kuka_sim.select_base(5)
    with connect(kuka_settings(kuka_sim)) as kuka:
        selected = kuka.read_pose()
        kuka_sim.set_base(1.0, 2.0, 3.0, 0.0, 0.0, 0.0)  # a program's own $BASE
        own = kuka.read_pose()
    assert selected.live_frame.number == 5
    assert selected.live_frame.name is None
    assert selected.live_frame.frame is not None
    assert_allclose(selected.live_frame.frame.position_mm, (1000.0, 200.0, 300.0), atol=1e-3)
    assert selected.readings["$ACT_BASE"] == "5"
    assert own.live_frame.number is None
    assert own.live_frame.frame is not None
    assert_allclose(own.live_frame.frame.position_mm, (1.0, 2.0, 3.0), atol=1e-4)


def test_a_pendant_edit_of_the_selected_base_is_what_the_next_read_sees(
    kuka_sim: KukaSimulator,
) -> None:
    kuka_sim.select_base(2)
    with connect(kuka_settings(kuka_sim)) as kuka:
        kuka.write_frame(FrameTarget(slot=2), Frame((100.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)))
        kuka_sim.set_base_data(2, 100.5, 0.0, 0.0, 0.0, 0.0, 0.0)  # edited at the pendant
        frame = kuka.read_frame(FrameTarget(slot=2))
        live = kuka.read_pose().live_frame
    assert frame.position_mm[0] == pytest.approx(100.5)
    assert live.frame is not None
    assert live.frame.position_mm[0] == pytest.approx(100.5)


def test_py_openshowvar_reads_the_base_the_connector_wrote(kuka_sim: KukaSimulator) -> None:
    """py-openshowvar (PyPI), a client written apart from this connector, reads BASE_DATA,
    BASE_TYPE and BASE_NAME as the connector left them."""
    from py_openshowvar import openshowvar

    with connect(kuka_settings(kuka_sim)) as kuka:
        kuka.write_frame(
            FrameTarget(kind="fixed_tool", slot=9, name="stand"),
            Frame((1250.5, -310.25, 80.125), (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))),
        )
    client = openshowvar(kuka_sim.host, kuka_sim.port)
    try:
        data = client.read("BASE_DATA[9]", debug=False)
        kind = client.read("BASE_TYPE[9]", debug=False)
        name = client.read("BASE_NAME[9,]", debug=False)
    finally:
        client.close()
    assert data.startswith(b"{FRAME: X 1250.5, Y -310.25, Z 80.125, A ")
    members = dict(m.split(" ") for m in data.decode()[len("{FRAME: ") : -1].split(", "))
    assert_allclose([float(members[k]) for k in "ABC"], [90.0, 0.0, 0.0], atol=1e-4)
    assert (kind, name) == (b"#TCP", b'"stand"')
