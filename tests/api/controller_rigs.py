"""One rig per controller protocol for the API tests: its simulator (from
tests/controllers/), the controller body that reaches it, the tool fields that address a tool
in it, and the operator's view of the tool data in the controller's own convention."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from app.kinematics.poses import kuka_abc_from_quaternion_wxyz, quaternion_wxyz_from_kuka_abc
from tests.controllers.kuka_sim import KukaSimulator

#: Every protocol with a simulator (more land with the connectors).
PROTOCOLS = ["kuka_kvp"]
TIMEOUT_S = 2.0


class Simulator(Protocol):
    host: str
    port: int
    stalled: bool

    def stop(self) -> None: ...


@dataclass
class Rig:
    """A running simulator and how a test talks to it."""

    protocol: str
    sim: Any
    tool_fields: dict[str, Any]

    def controller_body(self, **extra: Any) -> dict[str, Any]:
        """The PUT /v1/robots/{id}/controller body that reaches the simulator."""
        body = {
            "protocol": self.protocol,
            "host": self.sim.host,
            "port": self.sim.port,
            "timeout_s": TIMEOUT_S,
        }
        return {**body, **extra}

    def native(self) -> list[float]:
        """The tool data as the controller holds it, in its own convention."""
        if self.protocol == "kuka_kvp":
            return [float(v) for v in self.sim.tool(3)]
        raise NotImplementedError(self.protocol)

    def native_of(self, position_mm: list[float], quaternion: list[float]) -> list[float]:
        """A frame in the controller's own convention."""
        if self.protocol == "kuka_kvp":
            return [*position_mm, *map(float, kuka_abc_from_quaternion_wxyz(quaternion))]
        raise NotImplementedError(self.protocol)

    def held(self) -> tuple[list[float], list[float]]:
        """The tool data the controller holds as (position_mm, quaternion [w, x, y, z])."""
        values = self.native()
        if self.protocol == "kuka_kvp":
            return values[:3], [float(v) for v in quaternion_wxyz_from_kuka_abc(values[3:])]
        raise NotImplementedError(self.protocol)

    def set_behind_back(self, position_mm: list[float], quaternion: list[float]) -> None:
        """The operator types a frame into the pendant."""
        if self.protocol == "kuka_kvp":
            self.sim.set_tool(3, *self.native_of(position_mm, quaternion))
            return
        raise NotImplementedError(self.protocol)

    def wrong_password(self) -> dict[str, Any] | None:
        """Controller fields with a wrong password, or None when the protocol has none."""
        return None


@contextmanager
def rig(protocol: str) -> Iterator[Rig]:
    """The protocol's simulator, started on a free loopback port, stopped afterwards."""
    if protocol == "kuka_kvp":
        with KukaSimulator() as sim:
            yield Rig(protocol, sim, {"slot": 3})
        return
    raise NotImplementedError(protocol)


def assert_native_close(held: list[float], expected: list[float], *, mm: float, deg: float) -> None:
    """Position within `mm` and each angle within `deg` (angles compared modulo 360)."""
    held_a, exp_a = np.asarray(held), np.asarray(expected)
    assert np.all(np.abs(held_a[:3] - exp_a[:3]) <= mm), (held, expected)
    diff = (held_a[3:] - exp_a[3:] + 180.0) % 360.0 - 180.0
    assert np.all(np.abs(diff) <= deg), (held, expected)
