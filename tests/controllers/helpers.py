"""Shared checks for the connector tests: random tool data and frames, timing, secrets in
text."""

from __future__ import annotations

import re

import numpy as np
from scipy.spatial.transform import Rotation

from app.vendors.connector import Frame
from app.vendors.tool import ToolData, ToolLoad


def random_tool(seed: int, *, load: bool = True) -> ToolData:
    """A plausible tool: position within 400 mm of the flange, any orientation, a load."""
    rng = np.random.default_rng(seed)
    xyzw = Rotation.random(random_state=rng).as_quat(canonical=True)
    return ToolData(
        position_mm=tuple(float(v) for v in rng.uniform(-400, 400, 3)),  # type: ignore[arg-type]
        quaternion=(float(xyzw[3]), float(xyzw[0]), float(xyzw[1]), float(xyzw[2])),
        load=ToolLoad(
            mass_kg=float(rng.uniform(0.5, 20)),
            cog_mm=tuple(float(v) for v in rng.uniform(-100, 200, 3)),  # type: ignore[arg-type]
        )
        if load
        else None,
    )


def random_frame(seed: int) -> Frame:
    """A plausible base or fixed tool: within 2 m of the robot's base, any orientation."""
    rng = np.random.default_rng(seed)
    xyzw = Rotation.random(random_state=rng).as_quat(canonical=True)
    x, y, z = (float(v) for v in rng.uniform(-2000, 2000, 3))
    return Frame((x, y, z), (float(xyzw[3]), float(xyzw[0]), float(xyzw[1]), float(xyzw[2])))


def angle_between_deg(q_a: tuple[float, ...], q_b: tuple[float, ...]) -> float:
    """Rotation angle between two [w, x, y, z] quaternions, degrees."""
    a = Rotation.from_quat([q_a[1], q_a[2], q_a[3], q_a[0]])
    b = Rotation.from_quat([q_b[1], q_b[2], q_b[3], q_b[0]])
    return float(np.degrees((a.inv() * b).magnitude()))


def float32_tolerance(values: tuple[float, ...] | list[float]) -> float:
    """What a 32-bit REAL may lose on these values: one unit in the last place of the
    largest, plus the connector's six written decimals."""
    return float(np.spacing(np.float32(max(abs(v) for v in values)))) + 1e-6


def frame_number_refusal(
    slot: int | None, protocol: str, numbers: tuple[int, int], name: str
) -> str:
    """The pattern of the one refusal of a frame number (WireProtocol.frame_problem, at
    deployment as at registration): for a slot left out, what to set; else the range, the
    controller's `name` of it and the remedy."""
    low, high = numbers
    if slot is None:
        return re.escape(f"addresses frames by number: set the frame's slot ({low}-{high})")
    return re.escape(
        f"slot {slot} is outside {low}-{high}, the frame numbers of a {protocol} controller "
        f"({name}): give a slot from {low} to {high}"
    )
