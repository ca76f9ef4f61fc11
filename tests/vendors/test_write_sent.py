"""Each connector marks a failure that came after its write was handed to the socket
(`ControllerError.write_sent`): the controller may then hold the new frame. A failure before
the write leaves the mark off. The simulators go silent where a test's fault says
(tests/controllers/simbase.py `Faults`)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from app.vendors.connector import ControllerSettings, ControllerUnreachable, ToolTarget
from app.vendors.registry import connect
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fanuc_sim import FanucSimulator
from tests.controllers.fixtures import (
    abb_settings,
    fanuc_settings,
    kuka_settings,
    ur_settings,
    yaskawa_settings,
)
from tests.controllers.helpers import random_tool
from tests.controllers.kuka_sim import KukaSimulator
from tests.controllers.simbase import go_silent
from tests.controllers.ur_sim import UrSimulator
from tests.controllers.yaskawa_sim import YaskawaSimulator
from tests.polling import wait_for

#: The connector's whole session budget (connect, handshake, the write): a silent controller
#: costs a test this much, and a loaded machine can spend 0.3 s (the old value) before the
#: write leaves, which then failed "after" with write_sent False (FRC_Connect answered
#: 0.35 s late: False at 0.3, True at 1.0).
TIMEOUT_S = 1.0
SYMBOL = "T_ROB1/user/tTorch"
#: protocol: (the write as the simulator names it, the request before it and its count)
REQUESTS = {
    # KUKA reads $LOAD_DATA once to keep its other members before writing; the frame is
    # written first, the load after it
    "kuka_kvp": ("write $TOOL_DATA[3]", ("read $LOAD_DATA[3]", 1)),
    "fanuc_rmi": ("FRC_WriteUToolData", ("FRC_Connect", 1)),
    "abb_rws1": (
        "POST /rw/rapid/symbol/data/RAPID/T_ROB1/user/tTorch",
        ("GET /rw/rapid/symbol/data/RAPID/T_ROB1/user/tTorch", 1),
    ),
    "abb_rws2": (
        "POST /rw/rapid/symbol/RAPID/T_ROB1/user/tTorch/data",
        ("POST /rw/mastership/edit/request", 1),
    ),
    # Yaskawa applies a loaded TOOL.CND at its last block; the load's request (block 0)
    # carries no data, so silence there is before the write
    "yaskawa_hses": ("load TOOL.CND last block", ("load TOOL.CND", 1)),
    # UR: the program on the secondary interface; RTDE starts its data before any write
    "ur_rtde": ("script", ("RTDE_CONTROL_PACKAGE_START", 1)),
}


@pytest.fixture(params=list(REQUESTS))
def sim_and_settings(
    request: pytest.FixtureRequest,
) -> Iterator[tuple[str, Any, ControllerSettings]]:
    protocol = request.param
    sim: Any
    if protocol == "kuka_kvp":
        sim = KukaSimulator()
    elif protocol == "fanuc_rmi":
        sim = FanucSimulator()
    elif protocol == "yaskawa_hses":
        sim = YaskawaSimulator(transfer_timeout_s=0.2)
    elif protocol == "ur_rtde":
        sim = UrSimulator()
    else:
        sim = AbbRwsSimulator(version=1 if protocol == "abb_rws1" else 2)
    with sim:
        if protocol == "kuka_kvp":
            settings = kuka_settings(sim, timeout_s=TIMEOUT_S)
        elif protocol == "fanuc_rmi":
            settings = fanuc_settings(sim, timeout_s=TIMEOUT_S)
        elif protocol == "yaskawa_hses":
            settings = yaskawa_settings(sim, timeout_s=TIMEOUT_S)
        elif protocol == "ur_rtde":
            settings = ur_settings(sim, timeout_s=TIMEOUT_S)
        else:
            settings = abb_settings(sim, timeout_s=TIMEOUT_S)
        yield protocol, sim, settings


def _target(protocol: str) -> ToolTarget:
    if protocol == "ur_rtde":
        return ToolTarget()  # the live TCP
    return ToolTarget(symbol=SYMBOL) if protocol.startswith("abb") else ToolTarget(slot=3)


def _settle(sim: Any) -> None:
    """Until the simulator has seen the failed session's connection close (FANUC serves
    one RMI session at a time and frees it when the connection closes)."""
    wait_for(
        lambda: not getattr(sim, "session_open", False),
        timeout=10,
        what="the simulator to see the failed session's connection close",
        every=0.01,
    )


def _write(settings: ControllerSettings, protocol: str, seed: int = 7) -> ControllerUnreachable:
    with pytest.raises(ControllerUnreachable) as caught, connect(settings) as conn:
        conn.write_tool(_target(protocol), random_tool(seed))
    return caught.value


def test_a_controller_silent_after_the_write_marks_the_failure_write_sent(
    sim_and_settings: tuple[str, Any, ControllerSettings],
) -> None:
    protocol, sim, settings = sim_and_settings
    sim.fault = go_silent("after", REQUESTS[protocol][0])
    assert _write(settings, protocol).write_sent is True
    # and so when the write left but was never applied: the connector cannot tell
    sim.stalled = False
    _settle(sim)
    if protocol == "abb_rws2":
        sim.mastership_holder = None  # the silent session's, which this test is not about
    sim.fault = go_silent("before", REQUESTS[protocol][0])
    # another tool: UR confirms a write by tcp_offset showing it, which the first one set
    assert _write(settings, protocol, seed=8).write_sent is True


def test_a_controller_silent_before_the_write_leaves_the_mark_off(
    sim_and_settings: tuple[str, Any, ControllerSettings],
) -> None:
    protocol, sim, settings = sim_and_settings
    request, nth = REQUESTS[protocol][1]
    sim.fault = go_silent("before", request, nth=nth)
    assert _write(settings, protocol).write_sent is False
