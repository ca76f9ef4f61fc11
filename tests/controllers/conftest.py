"""Controller simulators as fixtures: each started on a free loopback port, stopped after.

`kuka_sim`, `fanuc_sim`, `abb_rws1_sim`, `abb_rws2_sim` are the running simulators (change
their tool data as an operator would: `set_tool`, `tool`, ...); `*_settings` the
`ControllerSettings` that reach them (timeout 2 s). Other test packages import these
fixtures with `from tests.controllers.conftest import *` or use the simulator classes.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from app.controllers import ControllerSettings
from tests.controllers.kuka_sim import KukaSimulator

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
