"""One rig per controller protocol for the API tests: its simulator (from
tests/controllers/), the controller body that reaches it, the tool fields that address a tool
in it, and the operator's view of the tool data in the controller's own convention."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.kinematics.poses import (
    fanuc_wpr_from_quaternion_wxyz,
    kuka_abc_from_quaternion_wxyz,
    quaternion_wxyz_from_fanuc_wpr,
    quaternion_wxyz_from_kuka_abc,
    rotation_angle_deg,
)
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fanuc_sim import FanucSimulator
from tests.controllers.kuka_sim import KukaSimulator

#: Every protocol, each with its simulator.
PROTOCOLS = ["kuka_kvp", "fanuc_rmi", "abb_rws1", "abb_rws2"]
TIMEOUT_S = 1.0
SLOT = 3
SYMBOL = "T_ROB1/user/tTorch"
#: The simulated ABB controllers' user (tests/controllers/abb_sim.py).
ABB_USER, ABB_PASSWORD = "Default User", "robotics"


@dataclass
class Rig:
    """A running simulator and how a test talks to it."""

    protocol: str
    sim: Any
    tool_fields: dict[str, Any]

    def controller_body(self, **extra: Any) -> dict[str, Any]:
        """The PUT /v1/robots/{id}/controller body that reaches the simulator."""
        body: dict[str, Any] = {
            "protocol": self.protocol,
            "host": self.sim.host,
            "port": self.sim.port,
            "timeout_s": TIMEOUT_S,
        }
        if self.protocol.startswith("abb"):
            # RWS 2.0's simulator has a self-signed certificate
            body |= {"username": ABB_USER, "password": ABB_PASSWORD, "tls_verify": False}
        return {**body, **extra}

    def native(self) -> list[float]:
        """The tool data as the controller holds it, in its own convention: KUKA X Y Z A B C,
        FANUC X Y Z W P R, ABB trans and rot (a quaternion q1..q4)."""
        if self.protocol.startswith("abb"):
            held = self.sim.tool(SYMBOL)
            return [*map(float, held.trans), *map(float, held.rot)]
        return [float(v) for v in self.sim.tool(SLOT)]

    def native_of(self, position_mm: list[float], quaternion: list[float]) -> list[float]:
        """A frame in the controller's own convention."""
        if self.protocol == "kuka_kvp":
            return [*position_mm, *map(float, kuka_abc_from_quaternion_wxyz(quaternion))]
        if self.protocol == "fanuc_rmi":
            return [*position_mm, *map(float, fanuc_wpr_from_quaternion_wxyz(quaternion))]
        return [*position_mm, *quaternion]

    def held(self) -> tuple[list[float], list[float]]:
        """The tool data the controller holds as (position_mm, quaternion [w, x, y, z])."""
        values = self.native()
        if self.protocol == "kuka_kvp":
            return values[:3], [float(v) for v in quaternion_wxyz_from_kuka_abc(values[3:])]
        if self.protocol == "fanuc_rmi":
            return values[:3], [float(v) for v in quaternion_wxyz_from_fanuc_wpr(values[3:])]
        return values[:3], values[3:]

    def set_behind_back(self, position_mm: list[float], quaternion: list[float]) -> None:
        """The operator types a frame into the pendant."""
        native = self.native_of(position_mm, quaternion)
        if self.protocol.startswith("abb"):
            self.sim.set_tool(SYMBOL, tuple(native[:3]), tuple(native[3:]))
        else:
            self.sim.set_tool(SLOT, *native)

    def assert_holds(self, position_mm: list[float], quaternion: list[float]) -> None:
        """The controller holds this frame within 0.001 mm and 0.001 deg, compared in its
        own convention (angles modulo 360; ABB's quaternion by the angle between them)."""
        held, expected = self.native(), self.native_of(position_mm, quaternion)
        assert np.all(np.abs(np.subtract(held[:3], expected[:3])) <= 0.001), (held, expected)
        if self.protocol.startswith("abb"):
            assert rotation_angle_deg(held[3:], expected[3:]) <= 0.001, (held, expected)
            return
        diff = (np.subtract(held[3:], expected[3:]) + 180.0) % 360.0 - 180.0
        assert np.all(np.abs(diff) <= 0.001), (held, expected)


@contextmanager
def rig(protocol: str) -> Iterator[Rig]:
    """The protocol's simulator, started on a free loopback port, stopped afterwards."""
    sim: Any
    fields: dict[str, Any]
    if protocol == "kuka_kvp":
        sim, fields = KukaSimulator(), {"slot": SLOT}
    elif protocol == "fanuc_rmi":
        sim, fields = FanucSimulator(), {"slot": SLOT}
    else:
        sim = AbbRwsSimulator(version=1 if protocol == "abb_rws1" else 2)
        fields = {"controller_symbol": SYMBOL}
    with sim:
        yield Rig(protocol, sim, fields)
