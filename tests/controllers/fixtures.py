"""Controller simulators as fixtures: each started on a free loopback port, stopped after.

`kuka_sim`, `fanuc_sim`, `abb_rws1_sim`, `abb_rws2_sim`, `yaskawa_sim`, `techman_sim`,
`ur_sim` are the running simulators (change their tool data as an operator would:
`set_tool`, `tool`, ...; `stalled = True` makes one stop answering; `stop()` switches it
off); `kuka_settings(sim)` etc. the `ControllerSettings` that reach them (timeout 2 s).
tests/controllers/conftest.py imports them; another test package does the same in its conftest
(`from tests.controllers.fixtures import kuka_sim, ...`).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from app.vendors.connector import ControllerSettings
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fanuc_sim import FanucSimulator
from tests.controllers.kuka_sim import KukaSimulator
from tests.controllers.techman_sim import TechmanSimulator
from tests.controllers.ur_sim import UrSimulator
from tests.controllers.yaskawa_sim import YaskawaSimulator

SIM_TIMEOUT_S = 2.0


@pytest.fixture
def kuka_sim() -> Iterator[KukaSimulator]:
    """KUKAVARPROXY on an in-memory KRC (tools 1-16)."""
    with KukaSimulator() as sim:
        yield sim


def kuka_settings(sim: KukaSimulator, *, timeout_s: float = SIM_TIMEOUT_S) -> ControllerSettings:
    """How to reach `sim` as a kuka_kvp controller."""
    return ControllerSettings(
        protocol="kuka_kvp",
        host=sim.host,
        port=sim.port,
        username=None,
        password=None,
        timeout_s=timeout_s,
    )


@pytest.fixture
def fanuc_sim() -> Iterator[FanucSimulator]:
    """A FANUC controller's Remote Motion Interface (UTOOL 1-10)."""
    with FanucSimulator() as sim:
        yield sim


def fanuc_settings(sim: FanucSimulator, *, timeout_s: float = SIM_TIMEOUT_S) -> ControllerSettings:
    """How to reach `sim` as a fanuc_rmi controller (its connect port)."""
    return ControllerSettings(
        protocol="fanuc_rmi",
        host=sim.host,
        port=sim.port,
        username=None,
        password=None,
        timeout_s=timeout_s,
    )


@pytest.fixture
def techman_sim() -> Iterator[TechmanSimulator]:
    """A TM robot whose project waits in a Listen node (Listen Node and Ethernet Slave)."""
    with TechmanSimulator() as sim:
        yield sim


def techman_settings(
    sim: TechmanSimulator, *, timeout_s: float = SIM_TIMEOUT_S
) -> ControllerSettings:
    """How to reach `sim` as a techman controller: its Listen Node and Ethernet Slave, each
    on its own port (`port` is the main service's, the Listen Node)."""
    return ControllerSettings(
        protocol="techman",
        host=sim.host,
        port=sim.listen_node_port,
        username=None,
        password=None,
        timeout_s=timeout_s,
        ports={"listen_node": sim.listen_node_port, "ethernet_slave": sim.ethernet_slave_port},
    )


@pytest.fixture
def abb_rws1_sim() -> Iterator[AbbRwsSimulator]:
    """RobotWare 6 Robot Web Services (HTTP, Digest; user "Default User", "robotics")."""
    with AbbRwsSimulator(version=1) as sim:
        yield sim


@pytest.fixture
def abb_rws2_sim() -> Iterator[AbbRwsSimulator]:
    """RobotWare 7 Robot Web Services 2.0 (HTTPS with a self-signed certificate, Basic)."""
    with AbbRwsSimulator(version=2) as sim:
        yield sim


def abb_settings(
    sim: AbbRwsSimulator,
    *,
    username: str = "Default User",
    password: str = "robotics",
    timeout_s: float = SIM_TIMEOUT_S,
) -> ControllerSettings:
    """How to reach `sim` as an abb_rws1 / abb_rws2 controller (RWS 2.0: tls_verify off,
    the simulator's certificate being self-signed)."""
    return ControllerSettings(
        protocol="abb_rws2" if sim.version == 2 else "abb_rws1",
        host=sim.host,
        port=sim.port,
        username=username,
        password=password,
        timeout_s=timeout_s,
        tls_verify=False,
    )


@pytest.fixture
def yaskawa_sim() -> Iterator[YaskawaSimulator]:
    """A YRC1000's High Speed Ethernet Server: robot control and file control (TOOL.CND, tools
    0-63) on two UDP ports; a transfer left behind times out after 0.5 s."""
    with YaskawaSimulator(transfer_timeout_s=0.5) as sim:
        yield sim


def yaskawa_settings(
    sim: YaskawaSimulator, *, timeout_s: float = SIM_TIMEOUT_S
) -> ControllerSettings:
    """How to reach `sim` as a yaskawa_hses controller (its robot and file ports)."""
    return ControllerSettings(
        protocol="yaskawa_hses",
        host=sim.host,
        port=sim.robot_port,
        username=None,
        password=None,
        timeout_s=timeout_s,
        ports={"robot": sim.robot_port, "file": sim.file_port},
    )


@pytest.fixture
def ur_sim() -> Iterator[UrSimulator]:
    """A UR e-Series controller: RTDE and the secondary interface on two free ports."""
    with UrSimulator() as sim:
        yield sim


def ur_settings(sim: UrSimulator, *, timeout_s: float = SIM_TIMEOUT_S) -> ControllerSettings:
    """How to reach `sim` as a ur_rtde controller (its two ports)."""
    return ControllerSettings(
        protocol="ur_rtde",
        host=sim.host,
        port=sim.rtde_port,
        username=None,
        password=None,
        timeout_s=timeout_s,
        ports={"rtde": sim.rtde_port, "secondary": sim.secondary_port},
    )
