"""ABB frames over RWS 1.0 and 2.0 against the simulator: a base's PERS wobjdata (uframe
written; robhold, ufprog, ufmec and oframe kept), a fixed tool's stationary tooldata, the
work object the robot moves in (the mechunit's wobj-name), refusals; cuts are
tests/vendors/test_frame_cuts.py's."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import pytest
from numpy.testing import assert_allclose

from app.vendors.connector import ControllerRefused, Frame, FrameTarget
from app.vendors.registry import connect
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fixtures import abb_settings
from tests.controllers.helpers import angle_between_deg, random_frame

FIXTURE = FrameTarget(kind="base", symbol="T_ROB1/user/wobjFixture")
STAND = FrameTarget(kind="fixed_tool", symbol="T_ROB1/user/tGripper")


@pytest.fixture(params=[1, 2], ids=["rws1", "rws2"])
def sim(request: pytest.FixtureRequest) -> Iterator[AbbRwsSimulator]:
    with AbbRwsSimulator(version=request.param, single_precision=False) as simulator:
        yield simulator


def table(sim: AbbRwsSimulator) -> tuple[dict[str, object], dict[str, object]]:
    """Every work object and tooldata the controller holds, copied."""
    return (
        {s: dataclasses.replace(w) for s, w in sim.wobjdata.items()},
        {s: dataclasses.replace(t) for s, t in sim.symbols.items()},
    )


@pytest.mark.parametrize("seed", range(3))
def test_a_base_is_the_wobjdatas_uframe_and_everything_else_is_kept(
    sim: AbbRwsSimulator, seed: int
) -> None:
    frame = random_frame(20 + seed)
    wobjs, tools = table(sim)
    held_before = sim.wobj(FIXTURE.symbol or "")
    with connect(abb_settings(sim)) as abb:
        assert abb.describe_frame(FIXTURE) == "T_ROB1/user/wobjFixture"
        abb.write_frame(FIXTURE, frame)
        back = abb.read_frame(FIXTURE)
    held = sim.wobj("T_ROB1/user/wobjFixture")
    assert_allclose(held.uframe[0], frame.position_mm, atol=1e-6)
    assert angle_between_deg(held.uframe[1], frame.quaternion) < 1e-6
    assert (held.robhold, held.ufprog, held.ufmec, held.oframe) == (
        held_before.robhold,
        held_before.ufprog,
        held_before.ufmec,
        held_before.oframe,
    )
    assert_allclose(back.position_mm, frame.position_mm, atol=1e-6)
    assert angle_between_deg(back.quaternion, frame.quaternion) < 1e-6
    after_wobjs, after_tools = table(sim)
    del wobjs["T_ROB1/user/wobjFixture"], after_wobjs["T_ROB1/user/wobjFixture"]
    assert after_wobjs == wobjs
    assert after_tools == tools
    if sim.version == 2:
        assert sim.mastership_holder is None


def test_a_fixed_tool_is_the_stationary_tooldatas_tframe_and_its_load_is_kept(
    sim: AbbRwsSimulator,
) -> None:
    before = sim.tool("T_ROB1/user/tGripper")
    with connect(abb_settings(sim)) as abb:
        abb.write_frame(STAND, Frame((1200.0, -300.0, 850.0), (0.0, 0.0, 1.0, 0.0)))
        back = abb.read_frame(STAND)
    held = sim.tool("T_ROB1/user/tGripper")
    assert held.trans == (1200.0, -300.0, 850.0)
    assert held.rot == (0.0, 0.0, 1.0, 0.0)
    assert (held.robhold, held.mass, held.cog, held.aom, held.inertia) == (
        False,
        before.mass,
        before.cog,
        before.aom,
        before.inertia,
    )
    assert back == Frame((1200.0, -300.0, 850.0), (0.0, 0.0, 1.0, 0.0))


def test_what_is_not_the_frames_data_is_refused_and_nothing_changes(
    sim: AbbRwsSimulator,
) -> None:
    before = table(sim)
    frame = random_frame(3)
    with connect(abb_settings(sim)) as abb:
        # a tool the robot holds is no stationary tool
        with pytest.raises(ControllerRefused, match=r"robhold TRUE.*not a stationary tool"):
            abb.write_frame(FrameTarget(kind="fixed_tool", symbol="T_ROB1/user/tTorch"), frame)
        # a tooldata named as a base's work object
        with pytest.raises(ControllerRefused, match="is not a wobjdata"):
            abb.write_frame(FrameTarget(symbol="T_ROB1/user/tTorch"), frame)
        with pytest.raises(ControllerRefused, match="Symbol not found"):
            abb.read_frame(FrameTarget(symbol="T_ROB1/user/wobjNothing"))
        with pytest.raises(ValueError, match="TASK/MODULE/SYMBOL"):
            abb.write_frame(FrameTarget(symbol="wobjTable"), frame)
        with pytest.raises(ValueError, match="controller_symbol"):
            abb.write_frame(FrameTarget(slot=1), frame)
    assert table(sim) == before
    assert sim.mastership_holder is None


def test_rws2_refuses_the_frame_while_the_flexpendant_holds_mastership() -> None:
    with AbbRwsSimulator(version=2) as sim:
        sim.mastership_holder = "FlexPendant"
        before = sim.wobj("T_ROB1/user/wobjTable")
        with (
            connect(abb_settings(sim)) as abb,
            pytest.raises(ControllerRefused, match=r"[Mm]astership"),
        ):
            abb.write_frame(FrameTarget(symbol="T_ROB1/user/wobjTable"), random_frame(4))
        assert sim.wobj("T_ROB1/user/wobjTable") == before
        assert sim.mastership_holder == "FlexPendant"


def test_the_live_frame_is_the_work_object_the_mechunit_names(sim: AbbRwsSimulator) -> None:
    sim.active_wobj = "wobjTable"
    with connect(abb_settings(sim)) as abb:
        pose = abb.read_pose()
    assert (pose.live_frame.number, pose.live_frame.name, pose.live_frame.frame) == (
        None,
        "wobjTable",
        None,
    )
    assert pose.readings["mechunit.wobj-name"] == "wobjTable"


def test_abb_robot_client_reads_the_mechunit_and_a_wobjdata_the_connector_wrote(
    abb_rws1_sim: AbbRwsSimulator,
) -> None:
    """abb-robot-client (RWS 1.0) reads the mechunit resource through its own session (no
    reader of its own for it: its GET with json=1) and the wobjdata as RAPID text."""
    from abb_robot_client.rws import RWS

    with connect(abb_settings(abb_rws1_sim)) as abb:
        abb.write_frame(
            FrameTarget(symbol="T_ROB1/user/wobjTable"),
            Frame((300.0, 600.0, 200.0), (1.0, 0.0, 0.0, 0.0)),
        )
    abb_rws1_sim.active_wobj = "wobjTable"
    client = RWS(abb_rws1_sim.base_url, "Default User", "robotics")
    assert (
        client.get_rapid_variable("user/wobjTable")
        == '[FALSE,TRUE,"",[[300,600,200],[1,0,0,0]],[[0,0,0],[1,0,0,0]]]'
    )
    state = client._do_get("rw/motionsystem/mechunits/ROB_1")["_embedded"]["_state"][0]
    assert (state["_type"], state["wobj-name"], state["tool-name"]) == (
        "ms-mechunit",
        "wobjTable",
        "tool0",
    )
