"""A frame write cut by a controller gone silent, on every protocol that writes frames: cut
before the write left, the failure is not `write_sent` and the controller holds the old
frame; the write left and was never applied, `write_sent` and the old frame; applied and
the answer lost, `write_sent` and the new frame. The next session then writes and reads
back: no session is left behind (ABB's mastership is released by the next session, FANUC's
RMI session and Techman's Listen node are free once the connection closed)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pytest

from app.vendors.connector import ControllerSettings, ControllerUnreachable, Frame, FrameTarget
from app.vendors.registry import connect
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fanuc_sim import FanucSimulator
from tests.controllers.fixtures import (
    abb_settings,
    fanuc_settings,
    kuka_settings,
    techman_settings,
)
from tests.controllers.kuka_sim import KukaSimulator
from tests.controllers.simbase import go_silent
from tests.controllers.techman_sim import TechmanSimulator
from tests.polling import wait_for

TIMEOUT_S = 1.0
WOBJ = "T_ROB1/user/wobjTable"


@dataclass(frozen=True)
class Case:
    """How a protocol's simulator is made, reached and read, and where its write is cut."""

    make: Callable[[], Any]
    settings: Callable[[Any, float], ControllerSettings]
    target: FrameTarget
    #: the frame's z as the simulator holds it
    held_z: Callable[[Any], float]
    #: the request before the write (None: the write is the session's first request)
    before: str | None
    write: str


CASES = {
    "kuka_kvp": Case(
        KukaSimulator,
        lambda sim, t: kuka_settings(sim, timeout_s=t),
        FrameTarget(slot=3),
        lambda sim: sim.base_data(3)[2],
        "read $ROBROOT_C",
        "write BASE_DATA[3]",
    ),
    "fanuc_rmi": Case(
        FanucSimulator,
        lambda sim, t: fanuc_settings(sim, timeout_s=t),
        FrameTarget(slot=4),
        lambda sim: sim.uframe(4)[2],
        "FRC_Connect",
        "FRC_WriteUFrameData",
    ),
    "abb_rws1": Case(
        lambda: AbbRwsSimulator(version=1),
        lambda sim, t: abb_settings(sim, timeout_s=t),
        FrameTarget(symbol=WOBJ),
        lambda sim: sim.wobj(WOBJ).uframe[0][2],
        f"GET /rw/rapid/symbol/data/RAPID/{WOBJ}",
        f"POST /rw/rapid/symbol/data/RAPID/{WOBJ}",
    ),
    "abb_rws2": Case(
        lambda: AbbRwsSimulator(version=2),
        lambda sim, t: abb_settings(sim, timeout_s=t),
        FrameTarget(symbol=WOBJ),
        lambda sim: sim.wobj(WOBJ).uframe[0][2],
        "POST /rw/mastership/edit/request",
        f"POST /rw/rapid/symbol/RAPID/{WOBJ}/data",
    ),
    "techman": Case(
        TechmanSimulator,
        lambda sim, t: techman_settings(sim, timeout_s=t),
        FrameTarget(),
        lambda sim: sim.current_base()[1][2],
        None,
        "ChangeBase",
    ),
}
CUTS = [
    ("before", "before", False, False),  # cut before the write left
    ("before", "write", True, False),  # the write left, never applied
    ("after", "write", True, True),  # applied, the answer lost
]


#: every protocol's cuts (a protocol whose write is its session's first request has no cut
#: before it)
PARAMS = [
    pytest.param(name, *cut, id=f"{name}-{cut[0]}-{cut[1]}")
    for name, spec in CASES.items()
    for cut in CUTS
    if spec.before is not None or cut[1] != "before"
]


def _write(spec: Case, sim: Any, z: float, timeout_s: float = 2.0) -> None:
    with connect(spec.settings(sim, timeout_s)) as conn:
        conn.write_frame(spec.target, Frame((0.0, 0.0, z), (1.0, 0.0, 0.0, 0.0)))


@pytest.mark.parametrize(("protocol", "moment", "where", "sent", "new"), PARAMS)
def test_a_cut_around_the_frame_write(
    protocol: str, moment: str, where: str, sent: bool, new: bool
) -> None:
    spec = CASES[protocol]
    request = spec.before if where == "before" else spec.write
    with spec.make() as sim:
        _cut_and_recover(spec, sim, moment, request, sent=sent, new=new)


def _cut_and_recover(
    spec: Case, sim: Any, moment: str, request: str | None, *, sent: bool, new: bool
) -> None:
    _write(spec, sim, 100.0)
    sim.fault = go_silent(moment, request)  # type: ignore[arg-type]
    with pytest.raises(ControllerUnreachable) as cut:
        _write(spec, sim, 250.0, TIMEOUT_S)
    assert cut.value.write_sent is sent
    assert spec.held_z(sim) == pytest.approx(250.0 if new else 100.0)
    sim.stalled = False
    wait_for(
        lambda: not getattr(sim, "session_open", False),
        timeout=10,
        what="the simulator to see the cut session's connection close",
        every=0.01,
    )
    _write(spec, sim, 300.0)  # nothing left behind
    with connect(spec.settings(sim, 2.0)) as conn:
        assert conn.read_frame(spec.target).position_mm[2] == pytest.approx(300.0)
