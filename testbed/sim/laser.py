"""Laser-beam device simulator: exact break/restore flange positions for a cylindrical tool.

The tool: a cylinder of radius `radius_mm` around the axis through `axis_point_mm` (where
the axis crosses the flange plane z_F = 0) with unit direction `axis_direction` (flange
frame, away from the flange), ending in a conical point at `length_mm` along the axis.
The flange rotation R0 is held fixed; the flange translates straight across each beam.

Why the closed form is exact: the beam plane z = z_L cuts the infinite cylinder in an
ellipse centred where the axis pierces the plane. Its support (half-extent) along a
horizontal unit vector e is radius * sqrt(1 + (u.e / u_z)^2) (u in base): the ellipse is
the circle projected along u onto the plane, and that projection is linear. A beam (an
infinite horizontal line) first and last touches the ellipse where it is tangent, i.e. at
centre -+ support along the sweep. tests/solvers/test_laser.py checks this independently:
at break and restore the beam line lies exactly `radius` from the tool axis.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from app.solvers.laser import Beam, LaserDevice, Sweep

#: The paper's robot (TM5M-900, 900 mm reach): beams in front of it, plane 100 mm up.
DEVICE = LaserDevice(beam_a_y_mm=-150.0, beam_b_x_mm=420.0, plane_z_mm=100.0)
#: Flange heights of the sweeps (base z, mm): the beam plane cuts the tool 10..50 mm above
#: its tip for a 150 mm tool.
HEIGHTS_MM = (200.0, 220.0, 240.0)


@dataclass(frozen=True)
class CylinderTool:
    """A round tool: radius, axis (point at z_F = 0 and direction, flange frame), length."""

    radius_mm: float
    axis_point_mm: NDArray[np.float64]
    axis_direction: NDArray[np.float64]
    length_mm: float
    tip_cone_mm: float = 6.0  # length of the conical point at the end

    @property
    def tcp_mm(self) -> NDArray[np.float64]:
        out: NDArray[np.float64] = self.axis_point_mm + self.length_mm * self.axis_direction
        return out

    @property
    def rotation(self) -> NDArray[np.float64]:
        """Tool frame (tool -> flange): Z along the axis, X the flange X orthogonal to it."""
        z = self.axis_direction
        x = np.array([1.0, 0.0, 0.0]) - z[0] * z
        x /= np.linalg.norm(x)
        return np.column_stack([x, np.cross(z, x), z])


def make_tool(
    *,
    offset_mm: tuple[float, float] = (0.0, 0.0),
    runout_deg: tuple[float, float] = (0.0, 0.0),
    radius_mm: float = 3.0,
    length_mm: float = 150.0,
) -> CylinderTool:
    """A tool with the paper's parameters: offset (dX, dY) at the flange, runout (tx, ty).

    u = Rx(tx) Ry(ty) z_hat: intrinsic X then Y, built with scipy (never by hand).
    """
    u = Rotation.from_euler("XY", runout_deg, degrees=True).apply([0.0, 0.0, 1.0])
    return CylinderTool(
        radius_mm=radius_mm,
        axis_point_mm=np.array([offset_mm[0], offset_mm[1], 0.0]),
        axis_direction=u,
        length_mm=length_mm,
    )


#: The paper's four tool states.
TOOL_STATES: dict[str, CylinderTool] = {
    "ideal": make_tool(),
    "offset": make_tool(offset_mm=(0.8, -0.5)),
    "runout": make_tool(runout_deg=(1.2, -0.7)),
    "offset_runout": make_tool(offset_mm=(-0.6, 0.9), runout_deg=(-0.9, 1.5)),
}


def tool_down_rotation(
    tilt_deg: tuple[float, float] = (0.0, 0.0), spin_deg: float = 0.0
) -> NDArray[np.float64]:
    """R0 (flange -> base) with the flange Z pointing down, tilted by (about X, about Y) deg."""
    rot = Rotation.from_euler("x", 180.0, degrees=True) * Rotation.from_euler(
        "XYZ", [tilt_deg[0], tilt_deg[1], spin_deg], degrees=True
    )
    out: NDArray[np.float64] = rot.as_matrix()
    return out


@dataclass(frozen=True)
class LaserData:
    """What the robot records: sweeps, the final descent, and the rotation held."""

    flange_rotation: NDArray[np.float64]
    sweeps: list[Sweep] = field(default_factory=list)
    descent_mm: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))


def axis_crossing(
    tool: CylinderTool, R0: NDArray[np.float64], flange_z: float, plane_z: float
) -> tuple[NDArray[np.float64], float]:
    """(axis point at base z = plane_z relative to the flange (base orientation), s along axis)."""
    a = R0 @ tool.axis_point_mm
    u = R0 @ tool.axis_direction
    s = (plane_z - flange_z - a[2]) / u[2]
    return a + s * u, float(s)


def half_width(tool: CylinderTool, R0: NDArray[np.float64], along: int) -> float:
    """Half-extent of the tool's section by a horizontal plane along base axis `along`."""
    u = R0 @ tool.axis_direction
    return float(tool.radius_mm * np.hypot(1.0, u[along] / u[2]))


def simulate(
    tool: CylinderTool,
    *,
    device: LaserDevice = DEVICE,
    flange_rotation: NDArray[np.float64] | None = None,
    heights_mm: Sequence[float] = HEIGHTS_MM,
    noise_mm: float = 0.0,
    rng: np.random.Generator | None = None,
    return_sweeps: bool = False,
    stand_off_mm: float = 30.0,
) -> LaserData:
    """Exact sweeps (beam A then B at each height) and descent; optional trigger noise.

    Noise: independent Gaussian, 1-sigma `noise_mm`, on each trigger along its sweep and on
    the descent's z. `return_sweeps` adds a sweep back across each beam (cancels latency).
    """
    R0 = tool_down_rotation() if flange_rotation is None else np.asarray(flange_rotation)
    rng = np.random.default_rng(0) if rng is None else rng
    u_b = R0 @ tool.axis_direction
    tilt = np.arctan2(np.hypot(u_b[0], u_b[1]), -u_b[2])
    sweeps: list[Sweep] = []
    for h in heights_mm:
        c, s = axis_crossing(tool, R0, h, device.plane_z_mm)
        reach = tool.radius_mm * np.tan(tilt)
        if not (s - reach > 0.0 and s + reach < tool.length_mm - tool.tip_cone_mm):
            raise ValueError(f"flange height {h} does not cut the cylindrical part of the tool")
        beams: tuple[tuple[Beam, int, float], ...] = (
            ("a", 1, device.beam_a_y_mm),
            ("b", 0, device.beam_b_x_mm),
        )
        for beam, along, target in beams:
            other = 1 - along
            # Hold the other coordinate so the tool passes stand_off_mm from the other beam.
            other_target = device.beam_b_x_mm if beam == "a" else device.beam_a_y_mm
            held = other_target - c[other] - stand_off_mm
            centre = target - c[along]  # flange coordinate putting the axis on the beam
            w = half_width(tool, R0, along)
            directions = (1.0, -1.0) if return_sweeps else (1.0,)
            for sign in directions:
                pts = []
                for value in (centre - sign * w, centre + sign * w):
                    p = np.empty(3)
                    p[along] = value + (rng.normal(0.0, noise_mm) if noise_mm > 0 else 0.0)
                    p[other] = held
                    p[2] = h
                    pts.append(p)
                sweeps.append(Sweep(beam=beam, break_mm=pts[0], restore_mm=pts[1]))
    tip_target = np.array([device.beam_b_x_mm, device.beam_a_y_mm, device.plane_z_mm])
    descent = tip_target - R0 @ tool.tcp_mm
    if noise_mm > 0:
        descent[2] += rng.normal(0.0, noise_mm)
    return LaserData(flange_rotation=R0, sweeps=sweeps, descent_mm=descent)
