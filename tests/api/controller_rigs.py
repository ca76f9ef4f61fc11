"""One rig per controller protocol for the API tests: its simulator (from
tests/controllers/), the controller body that reaches it, the tool fields that address a tool
in it, and the operator's view of the tool data in the controller's own convention.

The conventions are written here with scipy from the vendors' documents, not taken from
app.kinematics (the connectors' own conversions, which a deployment test would otherwise
judge with themselves):
- KUKA A, B, C (KSS 8 *Programming manual for system integrators*, FRAME; KUKA's A about Z,
  then B about the new Y, then C about the newest X: intrinsic Z-Y'-X''):
  R = Rz(A) Ry(B) Rx(C).
- FANUC W, P, R (yaw, pitch, roll about the fixed X, Y, Z axes, in that order):
  R = Rz(R) Ry(P) Rx(W).
- ABB ``orient`` [q1, q2, q3, q4] (RAPID reference, orient): q1 the scalar part, so
  [w, x, y, z] as tcpcal's quaternions.
- Yaskawa Rx, Ry, Rz of TOOL.CND (about the fixed X, Y, Z axes, as Yaskawa-Global/motoros2
  composes them): R = Rz(Rz) Ry(Ry) Rx(Rx), the product FANUC's W P R make.
- UR ``p[x, y, z, rx, ry, rz]`` (URScript manual, "Pose"): metres and a rotation vector
  (axis times angle, rad); the pendant shows x, y, z in mm, which `native` follows.
- Techman RX, RY, RZ (TMflow's Euler angles about the fixed X, Y, Z axes, as Techman's
  tm_driver composes them with setRPY): R = Rz(RZ) Ry(RY) Rx(RX).
Each product is composed from single-axis rotations as the documents write it; the angles
of a rotation are scipy's Euler angles for that product, checked against it."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fanuc_sim import FanucSimulator
from tests.controllers.kuka_sim import KukaSimulator
from tests.controllers.techman_sim import TechmanSimulator
from tests.controllers.ur_sim import UrSimulator
from tests.controllers.yaskawa_sim import YaskawaSimulator

#: Every protocol, each with its simulator.
PROTOCOLS = [
    "kuka_kvp",
    "fanuc_rmi",
    "abb_rws1",
    "abb_rws2",
    "yaskawa_hses",
    "ur_rtde",
    "techman",
]
#: The protocols whose deployment writes the robot's one live TCP (contract v1.3 scope).
LIVE_PROTOCOLS = {"ur_rtde", "techman"}
TIMEOUT_S = 1.0
SLOT = 3
SYMBOL = "T_ROB1/user/tTorch"
#: The simulated ABB controllers' user (tests/controllers/abb_sim.py).
ABB_USER, ABB_PASSWORD = "Default User", "robotics"


@pytest.fixture(autouse=True)
def secret_key(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """ABB controllers take a password, stored encrypted under this key. Autouse in each
    test module that imports it (``from tests.api.controller_rigs import secret_key as
    secret_key``)."""
    from app.config import get_settings

    monkeypatch.setenv("TCPCAL_SECRET_KEY", "controller-rigs-secret-key-0123456789")
    get_settings.cache_clear()
    yield
    get_settings.cache_clear()


def rotation_of(quaternion_wxyz: list[float] | tuple[float, ...]) -> Rotation:
    """A [w, x, y, z] quaternion (ABB's q1..q4) as a scipy Rotation (which takes x, y, z, w)."""
    w, x, y, z = (float(v) for v in quaternion_wxyz)
    return Rotation.from_quat([x, y, z, w])


def kuka_rotation(a: float, b: float, c: float) -> Rotation:
    """R = Rz(A) Ry(B) Rx(C), degrees."""
    return (
        Rotation.from_euler("z", a, degrees=True)
        * Rotation.from_euler("y", b, degrees=True)
        * Rotation.from_euler("x", c, degrees=True)
    )


def fanuc_rotation(w: float, p: float, r: float) -> Rotation:
    """R = Rz(R) Ry(P) Rx(W), degrees."""
    return (
        Rotation.from_euler("z", r, degrees=True)
        * Rotation.from_euler("y", p, degrees=True)
        * Rotation.from_euler("x", w, degrees=True)
    )


def techman_rotation(rx: float, ry: float, rz: float) -> Rotation:
    """R = Rz(RZ) Ry(RY) Rx(RX), degrees."""
    return (
        Rotation.from_euler("z", rz, degrees=True)
        * Rotation.from_euler("y", ry, degrees=True)
        * Rotation.from_euler("x", rx, degrees=True)
    )


#: protocol -> (the rotation of its three angles, scipy's name for the same product:
#: upper case intrinsic, lower case about fixed axes)
ANGLES = {
    "kuka_kvp": (kuka_rotation, "ZYX"),
    "fanuc_rmi": (fanuc_rotation, "xyz"),
    "yaskawa_hses": (fanuc_rotation, "xyz"),
    "techman": (techman_rotation, "xyz"),
}


@dataclass
class Rig:
    """A running simulator and how a test talks to it."""

    protocol: str
    sim: Any
    tool_fields: dict[str, Any]

    @property
    def scope(self) -> str:
        """Where a deployment holds: "live" (the robot's one live TCP) or "stored"."""
        return "live" if self.protocol in LIVE_PROTOCOLS else "stored"

    def controller_body(self, **extra: Any) -> dict[str, Any]:
        """The PUT /v1/robots/{id}/controller body that reaches the simulator."""
        body: dict[str, Any] = {
            "protocol": self.protocol,
            "host": self.sim.host,
            "timeout_s": TIMEOUT_S,
        }
        if self.protocol == "yaskawa_hses":
            body["ports"] = {"robot": self.sim.robot_port, "file": self.sim.file_port}
        elif self.protocol == "ur_rtde":
            body["ports"] = {"rtde": self.sim.rtde_port, "secondary": self.sim.secondary_port}
        elif self.protocol == "techman":
            body["ports"] = {
                "listen_node": self.sim.listen_node_port,
                "ethernet_slave": self.sim.ethernet_slave_port,
            }
        else:
            body["port"] = self.sim.port
        if self.protocol.startswith("abb"):
            # RWS 2.0's simulator has a self-signed certificate
            body |= {"username": ABB_USER, "password": ABB_PASSWORD, "tls_verify": False}
        return {**body, **extra}

    def native(self) -> list[float]:
        """The tool data as the controller holds it, in its own convention: KUKA X Y Z A B C,
        FANUC X Y Z W P R, ABB trans and rot (a quaternion q1..q4), UR x y z (mm) and the
        rotation vector (rad) of tcp_offset, the live TCP, Techman the current TCP's X Y Z RX
        RY RZ."""
        if self.protocol == "ur_rtde":
            pose = self.sim.tcp()
            return [*(v * 1000.0 for v in pose[:3]), *pose[3:]]
        if self.protocol == "techman":
            return [float(v) for v in self.sim.current_tcp()[1].values]
        if self.protocol.startswith("abb"):
            held = self.sim.tool(SYMBOL)
            return [*map(float, held.trans), *map(float, held.rot)]
        if self.protocol == "yaskawa_hses":
            position, angles = self.sim.tool(SLOT)
            return [*position, *angles]
        return [float(v) for v in self.sim.tool(SLOT)]

    def native_of(self, position_mm: list[float], quaternion: list[float]) -> list[float]:
        """A frame in the controller's own convention."""
        if self.protocol == "ur_rtde":
            return [*position_mm, *(float(v) for v in rotation_of(quaternion).as_rotvec())]
        if self.protocol not in ANGLES:
            return [*position_mm, *quaternion]
        compose, sequence = ANGLES[self.protocol]
        angles = [float(v) for v in rotation_of(quaternion).as_euler(sequence, degrees=True)]
        # the angles scipy gives are those of the documented product, or this rig is wrong
        assert (compose(*angles).inv() * rotation_of(quaternion)).magnitude() < 1e-9, angles
        return [*position_mm, *angles]

    def rotation(self) -> Rotation:
        """The rotation of the tool data the controller holds, read in its convention."""
        values = self.native()
        if self.protocol == "ur_rtde":
            return Rotation.from_rotvec(values[3:])
        if self.protocol in ANGLES:
            compose, _ = ANGLES[self.protocol]
            return compose(*values[3:])
        return rotation_of(values[3:])

    def held(self) -> tuple[list[float], list[float]]:
        """The tool data the controller holds as (position_mm, quaternion [w, x, y, z])."""
        x, y, z, w = self.rotation().as_quat(canonical=True)
        return self.native()[:3], [float(w), float(x), float(y), float(z)]

    def set_behind_back(self, position_mm: list[float], quaternion: list[float]) -> None:
        """The operator types a frame into the pendant (Techman: the project sets its TCP)."""
        native = self.native_of(position_mm, quaternion)
        if self.protocol == "ur_rtde":
            self.sim.pendant_set_tcp([*(v / 1000.0 for v in native[:3]), *native[3:]])
        elif self.protocol == "techman":
            self.sim.set_current_tcp(tuple(native))
        elif self.protocol.startswith("abb"):
            self.sim.set_tool(SYMBOL, tuple(native[:3]), tuple(native[3:]))
        elif self.protocol == "yaskawa_hses":
            self.sim.set_tool(SLOT, tuple(native[:3]), tuple(native[3:]))
        else:
            self.sim.set_tool(SLOT, *native)

    def assert_holds(self, position_mm: list[float], quaternion: list[float]) -> None:
        """The controller holds this frame within 0.001 mm and 0.001 deg: its position as
        given, its angles (or quaternion) composed in its own convention the rotation of
        `quaternion` (a pair of angles swapped, or composed in another order, is a rotation
        degrees away)."""
        held = self.native()
        assert np.all(np.abs(np.subtract(held[:3], position_mm)) <= 0.001), (held, position_mm)
        off_deg = np.degrees((self.rotation().inv() * rotation_of(quaternion)).magnitude())
        assert off_deg <= 0.001, (self.protocol, held, quaternion, off_deg)


@contextmanager
def rig(protocol: str) -> Iterator[Rig]:
    """The protocol's simulator, started on a free loopback port, stopped afterwards."""
    sim: Any
    fields: dict[str, Any]
    if protocol == "kuka_kvp":
        sim, fields = KukaSimulator(), {"slot": SLOT}
    elif protocol == "fanuc_rmi":
        sim, fields = FanucSimulator(), {"slot": SLOT}
    elif protocol == "yaskawa_hses":
        # a transfer a failed attempt left open is dropped 0.3 s after its last packet
        sim, fields = YaskawaSimulator(transfer_timeout_s=0.3), {"slot": SLOT}
    elif protocol == "ur_rtde":
        sim, fields = UrSimulator(), {}  # one live TCP, written by value
    elif protocol == "techman":
        sim, fields = TechmanSimulator(), {}
    else:
        sim = AbbRwsSimulator(version=1 if protocol == "abb_rws1" else 2)
        fields = {"controller_symbol": SYMBOL}
    with sim:
        yield Rig(protocol, sim, fields)
