"""Laser-beam runout and offset calibration with two crossed beams.

Device: two beams in the horizontal base plane z = z_L: beam A parallel to base X at
y = y_A, beam B parallel to base Y at x = x_B. The robot holds the flange rotation R0 fixed
(tool pointing down), sweeps the tool across each beam at two or more flange heights, and
finally moves straight down until the tip breaks a beam.

Why the midpoint works: the beam plane cuts a round tool in a circle (an ellipse when the
tool runs out); either is symmetric about the point where the tool axis pierces the plane,
and the first and last tangent lines parallel to a beam are symmetric about that centre.
So the midpoint of the break/restore flange coordinates puts the axis exactly on the beam:

    c_k = (x_B - xmid_k, y_A - ymid_k, z_L - h_k)    axis point relative to the flange, base
    q_k = R0^T c_k                                   the same point, flange frame

A constant trigger latency shifts break and restore alike along the sweep: sweeping back
over the same beam at the same height (both are averaged) cancels it.

Definitions used throughout:
- axis_point_flange_mm: where the tool axis crosses the flange plane z_F = 0 (flange frame);
  offset_mm = its (x, y).
- axis_direction_flange: unit vector of the axis, pointing away from the flange.
- runout_deg (tx, ty): u = Rx(tx) Ry(ty) z_hat (X-Y-Z Euler angles of the TCP frame,
  rotation about Z ignored), as scipy's Rotation.as_euler("XYZ") gives them.
- tool_length_mm: distance along the axis from axis_point_flange_mm to the tip.
- tip: the axis point at the beam plane when the final descent breaks a beam (a pointed
  tool; a flat-ended tool with runout breaks first at its rim, radius * sin(tilt) higher).
- TCP frame: Z along u, X the flange X made orthogonal to u, Y = Z x X.
- Heights: sweeps whose flange z agree within HEIGHT_TOL_MM (break and restore included)
  form one height; heights must be MIN_HEIGHT_SEPARATION_MM apart; each needs both beams.
- Uncertainty: trigger noise (1-sigma, mm, along each sweep for break and restore, and
  vertical for the descent) propagated linearly through the whole solution. Without a
  given noise figure and with >= 3 heights it is estimated from the line-fit residuals, on
  2 (K - 2) degrees of freedom, and the sigma is widened by t(0.975, nu) / 1.96 so that
  +-1.96 sigma remains a 95 % interval (Student's t).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.distributions import norm_ppf, t_ppf
from app.solvers.orientation import (
    SigmaEstimate,
    linear_sigma,
    quaternion_wxyz_from_matrix,
    rotation_error_deg,
)
from app.solvers.validation import check_finite, check_positions_mm, check_rotation_matrices

Beam = Literal["a", "b"]

#: Sweeps (and a sweep's break and restore) at one flange height agree in z within this, mm.
HEIGHT_TOL_MM = 0.5
#: Distinct heights must be at least this far apart, mm (the runout lever).
MIN_HEIGHT_SEPARATION_MM = 5.0
#: Shortest break-to-restore distance accepted, mm.
MIN_WIDTH_MM = 1e-3
#: The flange's +Z must point within this angle (deg) of straight down.
MAX_TOOL_TILT_DEG = 60.0
#: The descent's tip may lie this far (mm) beyond the tool's half-width from a beam line.
DESCENT_TOL_MM = 0.5
#: A sweep straying more than this (deg) from its nominal base axis earns a warning.
WARN_SWEEP_ANGLE_DEG = 5.0
#: Widths of one beam at different heights differing by more than this fraction: warning.
WARN_WIDTH_SPREAD = 0.2

_ALONG = {"a": 1, "b": 0}  # beam A is crossed moving along base Y, beam B along base X


@dataclass(frozen=True)
class LaserDevice:
    """Beam geometry in the base frame, mm: beam A at y, beam B at x, both at z = plane_z_mm."""

    beam_a_y_mm: float
    beam_b_x_mm: float
    plane_z_mm: float


@dataclass(frozen=True)
class Sweep:
    """One straight move across a beam: flange positions (3,) mm at break and at restore."""

    beam: Beam
    break_mm: ArrayLike | None
    restore_mm: ArrayLike | None


@dataclass(frozen=True)
class LaserSigma:
    """1-sigma of a laser result; `source` says where the noise figure came from."""

    tcp_mm: tuple[float, float, float]
    runout_deg: tuple[float, float]
    offset_mm: tuple[float, float]
    tool_length_mm: float
    rotation_deg: tuple[float, float, float]  # small rotations about tool x, y, z
    source: SigmaEstimate
    trigger_noise_mm: float  # the figure propagated (0 when source is "none")


@dataclass(frozen=True)
class LaserResult:
    """Tool axis, TCP and frame from laser sweeps; see the module docstring for definitions."""

    tcp_mm: FloatArray
    rotation: FloatArray
    quaternion_wxyz: tuple[float, float, float, float]
    axis_point_flange_mm: FloatArray
    axis_direction_flange: FloatArray
    runout_deg: tuple[float, float]
    offset_mm: tuple[float, float]
    tool_length_mm: float
    widths_mm: tuple[float, ...]
    residuals_mm: tuple[float, ...]
    heights_mm: tuple[float, ...]
    sigma: LaserSigma
    warnings: tuple[str, ...]


@dataclass(frozen=True)
class DeviceFit:
    """Quality of a taught device: per-height residuals, 1-sigma of (y_A, x_B, z_L)."""

    residuals_mm: tuple[float, ...]
    sigma_mm: tuple[float, float, float]  # beam_a_y, beam_b_x, plane_z
    sigma_source: SigmaEstimate
    axis_direction_flange: FloatArray
    widths_mm: tuple[float, ...]
    warnings: tuple[str, ...]


# --------------------------------------------------------------------------------------
# Input parsing
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Parsed:
    R0: FloatArray
    beams: tuple[str, ...]
    breaks: FloatArray  # (n, 3)
    restores: FloatArray  # (n, 3)
    groups: tuple[tuple[int, ...], ...]  # sweep indices per height, by increasing z
    heights: FloatArray  # (K,) flange z per height
    descent: FloatArray  # (3,)
    warnings: tuple[str, ...]

    def noisy_inputs(self) -> FloatArray:
        """The values trigger noise acts on: along-sweep break, restore; then descent z."""
        along = [_ALONG[b] for b in self.beams]
        idx = np.arange(len(self.beams))
        return np.concatenate(
            [self.breaks[idx, along], self.restores[idx, along], [self.descent[2]]]
        )

    def mids(self, x: FloatArray) -> FloatArray:
        n = len(self.beams)
        out: FloatArray = 0.5 * (x[:n] + x[n : 2 * n])
        return out

    def widths(self) -> FloatArray:
        along = [_ALONG[b] for b in self.beams]
        idx = np.arange(len(self.beams))
        out: FloatArray = np.abs(self.restores[idx, along] - self.breaks[idx, along])
        return out


def _parse(flange_rotation: ArrayLike, sweeps: Sequence[Sweep], descent_mm: ArrayLike) -> _Parsed:
    """Check the pose, the descent and every sweep, and group the sweeps by flange height."""
    R0 = _checked_flange_rotation(flange_rotation)
    descent = np.asarray(descent_mm, dtype=np.float64)
    if descent.shape != (3,):
        raise InvalidInput("invalid-sweep", "descent_mm needs 3 values (mm)", loc=("descent_mm",))
    descent = check_positions_mm(descent[None], loc=("descent_mm",))[0]
    if not sweeps:
        raise InvalidInput(
            "too-few-poses",
            "no sweeps: sweep both beams at two or more flange heights",
            loc=("sweeps",),
        )
    breaks = np.empty((len(sweeps), 3))
    restores = np.empty((len(sweeps), 3))
    warnings: list[str] = []
    for i, sweep in enumerate(sweeps):
        breaks[i], restores[i], warning = _checked_sweep(i, sweep)
        if warning:
            warnings.append(warning)
    beams = tuple(s.beam for s in sweeps)
    groups, heights = _height_groups(0.5 * (breaks[:, 2] + restores[:, 2]), beams)
    return _Parsed(
        R0=R0,
        beams=beams,
        breaks=breaks,
        restores=restores,
        groups=groups,
        heights=heights,
        descent=descent,
        warnings=tuple(warnings),
    )


def _checked_flange_rotation(flange_rotation: ArrayLike) -> FloatArray:
    """The flange orientation (3, 3), refused unless the tool points down into the beams."""
    R0: FloatArray = check_rotation_matrices(
        np.asarray(flange_rotation, dtype=np.float64)[None], loc=("poses",)
    )[0]
    down = float(-R0[2, 2])  # flange +Z in base, z component, negated
    tilt = float(np.degrees(np.arccos(np.clip(down, -1.0, 1.0))))
    if tilt > MAX_TOOL_TILT_DEG:
        raise InvalidInput(
            "degenerate-poses",
            f"the flange's Z axis is {tilt:.0f} deg from straight down; the laser method needs "
            f"the tool pointing down (within {MAX_TOOL_TILT_DEG:g} deg) to cross the beam plane",
            loc=("poses", 0, "rotation"),
            context={"tilt_deg": tilt},
        )
    return R0


def _checked_position(i: int, sweep: Sweep, name: str) -> FloatArray:
    """Sweep i's break_mm or restore_mm as (3,) mm, refused when missing or malformed."""
    value = sweep.break_mm if name == "break_mm" else sweep.restore_mm
    if value is None:
        raise InvalidInput(
            "invalid-sweep",
            f"sweep {i + 1}: no {name.removesuffix('_mm')} position: the tool must break "
            f"and then restore beam {sweep.beam.upper()}; a beam the tool never crossed "
            "cannot be used",
            loc=("sweeps", i, name),
        )
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise InvalidInput(
            "invalid-sweep", f"sweep {i + 1}: {name} needs 3 values (mm)", loc=("sweeps", i, name)
        )
    position: FloatArray = check_positions_mm(arr[None], loc=("sweeps", i, name))[0]
    return position


def _checked_sweep(i: int, sweep: Sweep) -> tuple[FloatArray, FloatArray, str | None]:
    """Break and restore of sweep i, refused unless a horizontal move across its beam;
    a warning when the move strays from the beam's crossing direction."""
    if sweep.beam not in ("a", "b"):
        raise InvalidInput(
            "invalid-sweep",
            f"sweep {i + 1}: beam must be 'a' (parallel to base X) or 'b' (parallel to base Y), "
            f"got {sweep.beam!r}",
            loc=("sweeps", i, "beam"),
        )
    brk = _checked_position(i, sweep, "break_mm")
    restore = _checked_position(i, sweep, "restore_mm")
    d = restore - brk
    a = _ALONG[sweep.beam]
    along, off = abs(float(d[a])), abs(float(d[1 - a]))
    beam, axis, other = sweep.beam.upper(), "xy"[a].upper(), "xy"[1 - a].upper()
    if float(np.linalg.norm(d)) < MIN_WIDTH_MM:
        raise InvalidInput(
            "invalid-sweep",
            f"sweep {i + 1}: break and restore are the same position; the flange must move "
            f"across beam {beam} between them",
            loc=("sweeps", i, "restore_mm"),
        )
    if abs(float(d[2])) > HEIGHT_TOL_MM:
        raise InvalidInput(
            "invalid-sweep",
            f"sweep {i + 1}: the flange height changed by {d[2]:.2f} mm between break and "
            f"restore; sweep horizontally (within {HEIGHT_TOL_MM:g} mm)",
            loc=("sweeps", i, "restore_mm"),
        )
    if off > along or along < MIN_WIDTH_MM:
        raise InvalidInput(
            "invalid-sweep",
            f"sweep {i + 1}: the flange moved mostly along base {other}; "
            f"beam {beam} is crossed by moving along base {axis}",
            loc=("sweeps", i, "restore_mm"),
        )
    angle = float(np.degrees(np.arctan2(off, along)))
    warning = None
    if angle > WARN_SWEEP_ANGLE_DEG:
        warning = (
            f"sweep {i + 1} strays {angle:.1f} deg from base {axis}; only its {axis} motion is used"
        )
    return brk, restore, warning


def _height_groups(
    z: FloatArray, beams: tuple[str, ...]
) -> tuple[tuple[tuple[int, ...], ...], FloatArray]:
    """Sweeps grouped by flange height z (mm), lowest first, and each group's height.

    Refused unless there are two or more heights, clearly apart, each with both beams swept.
    """
    groups: list[list[int]] = []
    for i in np.argsort(z, kind="stable"):
        if groups and z[i] - z[groups[-1][0]] <= HEIGHT_TOL_MM:
            groups[-1].append(int(i))
        else:
            groups.append([int(i)])
    heights = np.array([float(np.mean(z[g])) for g in groups])
    for k in range(1, len(groups)):
        gap = heights[k] - heights[k - 1]
        if gap < MIN_HEIGHT_SEPARATION_MM:
            raise InvalidInput(
                "invalid-sweep",
                f"sweep {groups[k][0] + 1} is {gap:.2f} mm above the sweeps at flange z "
                f"{heights[k - 1]:.2f} mm: sweeps at one height must agree within "
                f"{HEIGHT_TOL_MM:g} mm and heights must be at least "
                f"{MIN_HEIGHT_SEPARATION_MM:g} mm apart",
                loc=("sweeps", groups[k][0], "break_mm"),
            )
    for g, h in zip(groups, heights, strict=True):
        present = {beams[i] for i in g}
        for beam in ("a", "b"):
            if beam not in present:
                raise InvalidInput(
                    "invalid-sweep",
                    f"at flange z {h:.2f} mm there is no sweep across beam {beam.upper()}; "
                    "every height needs a sweep across both beams",
                    loc=("sweeps", g[0], "beam"),
                )
    if len(groups) < 2:
        raise InvalidInput(
            "too-few-poses",
            f"all sweeps are at one flange height ({heights[0]:.2f} mm); sweep both beams at "
            f"two or more heights at least {MIN_HEIGHT_SEPARATION_MM:g} mm apart",
            loc=("sweeps",),
        )
    return tuple(tuple(g) for g in groups), heights


# --------------------------------------------------------------------------------------
# Geometry
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Line:
    """Tool axis relative to the flange, base orientation: point at c_z = 0, slopes, fit."""

    alpha: FloatArray  # (2,) x, y at c_z = 0
    beta: FloatArray  # (2,) dx/dc_z, dy/dc_z
    c: FloatArray  # (K, 3) axis points per height
    weights: FloatArray  # (K, 2) sweeps per height for beam B (x) and A (y)

    def residuals(self) -> FloatArray:
        pred = self.alpha[None, :] + self.c[:, 2:3] * self.beta[None, :]
        out: FloatArray = self.c[:, :2] - pred
        return out

    def direction_base(self) -> FloatArray:
        """Unit axis direction in base orientation, pointing down (away from the flange)."""
        v = -np.array([self.beta[0], self.beta[1], 1.0])
        out: FloatArray = v / np.linalg.norm(v)
        return out


def _fit_line(
    p: _Parsed, mids: FloatArray, beam_b_x: float, beam_a_y: float, plane_z: float
) -> _Line:
    K = len(p.groups)
    c = np.empty((K, 3))
    w = np.empty((K, 2))
    for k, g in enumerate(p.groups):
        gb = [i for i in g if p.beams[i] == "b"]
        ga = [i for i in g if p.beams[i] == "a"]
        c[k] = (beam_b_x - mids[gb].mean(), beam_a_y - mids[ga].mean(), plane_z - p.heights[k])
        w[k] = (len(gb), len(ga))
    alpha = np.empty(2)
    beta = np.empty(2)
    for j in range(2):
        # Weighted least squares of c_j on c_z: the heights are exact, the midpoints noisy.
        A = np.column_stack([np.ones(K), c[:, 2]]) * np.sqrt(w[:, j])[:, None]
        sol = np.linalg.lstsq(A, c[:, j] * np.sqrt(w[:, j]), rcond=None)[0]
        alpha[j], beta[j] = sol
    return _Line(alpha=alpha, beta=beta, c=c, weights=w)


@dataclass(frozen=True)
class _Tool:
    line: _Line
    axis_point: FloatArray  # flange frame, z = 0
    u: FloatArray  # flange frame, unit, away from the flange
    length: float
    tcp: FloatArray
    Q: FloatArray
    runout: FloatArray  # deg (tx, ty)


def _tool_frame(u: FloatArray) -> FloatArray:
    x = np.array([1.0, 0.0, 0.0])
    xo = x - float(x @ u) * u
    if float(np.linalg.norm(xo)) < 1e-9:
        # Cannot happen for an accepted tool (|u_z| >= 0.5), kept so the helper is total.
        xo = np.array([0.0, 1.0, 0.0]) - u[1] * u
    xo = xo / np.linalg.norm(xo)
    return np.column_stack([xo, np.cross(u, xo), u])


def _solve_tool(p: _Parsed, x: FloatArray, dev: LaserDevice) -> _Tool:
    line = _fit_line(p, p.mids(x), dev.beam_b_x_mm, dev.beam_a_y_mm, dev.plane_z_mm)
    R0 = p.R0
    u_b = line.direction_base()
    u = R0.T @ u_b
    if abs(float(u[2])) < 0.5:
        raise InvalidInput(
            "degenerate-poses",
            "the sweeps put the tool axis within 30 deg of the flange plane: the laser method "
            "needs a tool that points away from the flange (check the sweep positions)",
            loc=("sweeps",),
        )
    p0 = R0.T @ np.array([line.alpha[0], line.alpha[1], 0.0])
    axis_point = p0 - (p0[2] / u[2]) * u
    descent = p.descent.copy()
    descent[2] = x[-1]
    length = float((dev.plane_z_mm - descent[2] - (R0 @ axis_point)[2]) / u_b[2])
    tcp = axis_point + length * u
    Q = _tool_frame(u)
    return _Tool(line, axis_point, u, length, tcp, Q, _runout_deg(u))


def _runout_deg(u: FloatArray) -> FloatArray:
    """(tx, ty) deg: the first two intrinsic X-Y-Z Euler angles of the tool frame whose Z is u,
    as Rotation.as_euler("XYZ") gives them. Only the frame's Z column enters them
    (Rx(a) Ry(b) Rz(c) has Z column [sin b, -sin a cos b, cos a cos b]), and with |u_z| >=
    0.5 (an accepted tool) cos b > 0, so two arctangents give them without the rotation
    objects the sigma's finite differences would build some fifty times a solve."""
    tx = math.atan2(-float(u[1]), float(u[2]))
    ty = math.atan2(float(u[0]), math.hypot(float(u[1]), float(u[2])))
    out: FloatArray = np.degrees(np.array([tx, ty]))
    return out


def _noise(
    p: _Parsed, line: _Line, trigger_noise_mm: float | None, warnings: list[str]
) -> tuple[float, SigmaEstimate, float]:
    """The trigger noise to propagate, where it came from, and the factor that widens the
    propagated 1-sigma so that +-1.96 sigma stays a 95 % interval (1 for a given figure).

    Estimated from K heights the noise has only 2 (K - 2) degrees of freedom (2 with three
    heights): the error over the estimated sigma then follows Student's t, not the normal
    law, and its 97.5 % point is t(0.975, nu) / 1.96 times larger (2.2x for nu = 2).
    """
    if trigger_noise_mm is not None:
        return trigger_noise_mm, "configured", 1.0
    K = len(p.groups)
    if K >= 3:
        res = line.residuals()
        chi2 = float(np.sum(line.weights * res**2))
        nu = 2 * (K - 2)
        sigma_mid = np.sqrt(chi2 / nu)
        widen = _widening(nu)
        # A midpoint averages two triggers: sigma_mid = sigma_trigger / sqrt(2).
        return float(np.sqrt(2.0) * sigma_mid), "residuals", widen
    warnings.append(
        "no trigger noise given and only two heights: the uncertainty was not estimated "
        "(give trigger_noise_mm or sweep a third height)"
    )
    return 0.0, "none", 1.0


def _widening(nu: float) -> float:
    """t(0.975, nu) / 1.96: the factor that keeps +-1.96 sigma a 95 % interval when the
    noise behind sigma was estimated on nu degrees of freedom (Student's t)."""
    return float(t_ppf(0.975, nu) / norm_ppf(0.975))


def _check_noise(value: float | None) -> float | None:
    if value is None:
        return None
    v = float(check_finite(value, loc=("options", "trigger_noise_mm")))
    if v < 0.0:
        raise InvalidInput(
            "invalid-options",
            f"trigger_noise_mm must be zero or positive, got {v:g}",
            loc=("options", "trigger_noise_mm"),
        )
    return v


def _check_widths(p: _Parsed, warnings: list[str]) -> FloatArray:
    widths = p.widths()
    for beam in ("a", "b"):
        wb = np.array([widths[i] for i in range(len(p.beams)) if p.beams[i] == beam])
        if wb.min() < (1.0 - WARN_WIDTH_SPREAD) * wb.max():
            warnings.append(
                f"beam {beam.upper()} widths range {wb.min():.3f}..{wb.max():.3f} mm across "
                "heights: the swept section is not a constant cylinder (tapered tool, or a "
                "sweep that did not cross the same part)"
            )
    return widths


def _check_line_residuals(p: _Parsed, line: _Line, widths: FloatArray) -> None:
    if len(p.groups) < 3:
        return
    res = np.linalg.norm(line.residuals(), axis=1)
    for k, g in enumerate(p.groups):
        half = 0.5 * float(min(widths[i] for i in g))
        if res[k] > half:
            raise InvalidInput(
                "invalid-sweep",
                f"at flange z {p.heights[k]:.2f} mm the sweeps put the tool axis {res[k]:.2f} mm "
                f"off the straight line through the other heights, more than the tool's "
                f"half-width ({half:.2f} mm): a sweep did not cross the tool it should have",
                loc=("sweeps", g[0], "break_mm"),
                context={"residual_mm": float(res[k])},
            )


# --------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------


def solve_laser(
    *,
    flange_rotation: ArrayLike,
    sweeps: Sequence[Sweep],
    descent_mm: ArrayLike,
    device: LaserDevice,
    trigger_noise_mm: float | None = None,
) -> LaserResult:
    """Tool axis, runout, offset, length, TCP and frame from laser sweeps and a descent.

    flange_rotation (3, 3): R0, flange -> base, held throughout. sweeps: two or more flange
    heights, both beams at each. descent_mm (3,): flange position when the tip broke a beam
    on the final straight move down. trigger_noise_mm: 1-sigma of a trigger position.
    """
    noise_in = _check_noise(trigger_noise_mm)
    dev_arr = check_finite(
        [device.beam_a_y_mm, device.beam_b_x_mm, device.plane_z_mm], loc=("laser",)
    )
    dev = LaserDevice(float(dev_arr[0]), float(dev_arr[1]), float(dev_arr[2]))
    p = _parse(flange_rotation, sweeps, descent_mm)
    warnings = list(p.warnings)
    for k, h in enumerate(p.heights):
        if h <= dev.plane_z_mm:
            raise InvalidInput(
                "invalid-sweep",
                f"at flange z {h:.2f} mm the flange is not above the beam plane "
                f"(z = {dev.plane_z_mm:.2f} mm): the tool cannot have crossed the beams there",
                loc=("sweeps", p.groups[k][0], "break_mm"),
            )
    x0 = p.noisy_inputs()
    tool = _solve_tool(p, x0, dev)
    widths = _check_widths(p, warnings)
    _check_line_residuals(p, tool.line, widths)
    _check_descent(p, tool, dev, widths)
    noise, source, widen = _noise(p, tool.line, noise_in, warnings)
    sigma = _laser_sigma(p, x0, dev, tool, noise, widen, source)
    return LaserResult(
        tcp_mm=tool.tcp,
        rotation=tool.Q,
        quaternion_wxyz=quaternion_wxyz_from_matrix(tool.Q),
        axis_point_flange_mm=tool.axis_point,
        axis_direction_flange=tool.u,
        runout_deg=(float(tool.runout[0]), float(tool.runout[1])),
        offset_mm=(float(tool.axis_point[0]), float(tool.axis_point[1])),
        tool_length_mm=tool.length,
        widths_mm=tuple(float(w) for w in widths),
        residuals_mm=tuple(float(r) for r in np.linalg.norm(tool.line.residuals(), axis=1)),
        heights_mm=tuple(float(h) for h in p.heights),
        sigma=sigma,
        warnings=tuple(warnings),
    )


def _check_descent(p: _Parsed, tool: _Tool, dev: LaserDevice, widths: FloatArray) -> None:
    """The tip at the descent must lie beyond every swept section and on (one of) the beams."""
    R0 = p.R0
    u_b = R0 @ tool.u
    s_k = (tool.line.c[:, 2] - (R0 @ tool.axis_point)[2]) / u_b[2]
    if tool.length <= float(s_k.max()):
        raise InvalidInput(
            "invalid-sweep",
            f"the descent puts the tip {float(s_k.max()) - tool.length:.2f} mm above the "
            "lowest swept section of the tool: the final move down must start above the beam "
            "crossing and stop when the tip breaks a beam",
            loc=("descent_mm",),
        )
    tip_b = p.descent + R0 @ tool.tcp
    miss = min(abs(tip_b[1] - dev.beam_a_y_mm), abs(tip_b[0] - dev.beam_b_x_mm))
    allowed = 0.5 * float(widths.mean()) + DESCENT_TOL_MM
    if miss > allowed:
        raise InvalidInput(
            "invalid-sweep",
            f"at the descent the tip is {miss:.2f} mm from the nearest beam (at most "
            f"{allowed:.2f} mm for this tool): it cannot have broken a beam there; place the "
            "tool axis over the beam crossing before moving down",
            loc=("descent_mm",),
            context={"miss_mm": float(miss)},
        )


def _laser_sigma(
    p: _Parsed,
    x0: FloatArray,
    dev: LaserDevice,
    tool: _Tool,
    noise: float,
    widen: float,
    source: SigmaEstimate,
) -> LaserSigma:
    """1-sigma of every output, the trigger noise propagated through the whole solve."""

    def outputs(x: FloatArray) -> FloatArray:
        t = _solve_tool(p, x, dev)
        return np.concatenate(
            [
                t.tcp,
                t.runout,
                t.axis_point[:2],
                [t.length],
                rotation_error_deg(tool.Q, t.Q),
            ]
        )

    sig = linear_sigma(outputs, x0, np.full(x0.size, noise)) if noise > 0 else np.zeros(11)
    sig = widen * sig
    return LaserSigma(
        tcp_mm=(float(sig[0]), float(sig[1]), float(sig[2])),
        runout_deg=(float(sig[3]), float(sig[4])),
        offset_mm=(float(sig[5]), float(sig[6])),
        tool_length_mm=float(sig[7]),
        rotation_deg=(float(sig[8]), float(sig[9]), float(sig[10])),
        source=source,
        trigger_noise_mm=noise,
    )


def _teach(
    p: _Parsed, x: FloatArray, t: FloatArray, u: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """(device [y_A, x_B, z_L], per-height [x_B_k, y_A_k]) for trusted tcp t and axis u."""
    R0 = p.R0
    mids = p.mids(x)
    plane_z = float(x[-1] + (R0 @ t)[2])
    u_b = R0 @ u
    per = np.empty((len(p.groups), 2))
    wts = np.empty((len(p.groups), 2))
    for k, g in enumerate(p.groups):
        lam = (plane_z - p.heights[k] - (R0 @ t)[2]) / u_b[2]
        c = R0 @ t + lam * u_b
        gb = [i for i in g if p.beams[i] == "b"]
        ga = [i for i in g if p.beams[i] == "a"]
        per[k] = (mids[gb].mean() + c[0], mids[ga].mean() + c[1])
        wts[k] = (len(gb), len(ga))
    x_b = float(np.average(per[:, 0], weights=wts[:, 0]))
    y_a = float(np.average(per[:, 1], weights=wts[:, 1]))
    return np.array([y_a, x_b, plane_z]), per


def teach_device(
    *,
    flange_rotation: ArrayLike,
    sweeps: Sequence[Sweep],
    descent_mm: ArrayLike,
    tcp_mm: ArrayLike,
    tool_axis_flange: ArrayLike | None = None,
    trigger_noise_mm: float | None = None,
) -> tuple[LaserDevice, DeviceFit]:
    """Beam geometry (y_A, x_B, z_L) from the sweeps and descent of a trusted tool.

    tcp_mm (3,): the trusted tool's TCP (flange frame), its tip. tool_axis_flange (3,): its
    axis direction away from the flange (from its trusted orientation, the tool Z); None:
    the direction measured by the sweeps themselves (which does not need the device).
    z_L is the tip's base z at the descent; x_B and y_A average the heights' axis crossings.
    """
    noise_in = _check_noise(trigger_noise_mm)
    t = check_finite(tcp_mm, loc=("teach", "tcp_mm"))
    if t.shape != (3,):
        raise InvalidInput("invalid-options", "tcp_mm needs 3 values (mm)", loc=("teach", "tcp_mm"))
    p = _parse(flange_rotation, sweeps, descent_mm)
    warnings = list(p.warnings)
    x0 = p.noisy_inputs()
    # The axis direction follows from midpoint differences alone: any device will do.
    probe = _fit_line(p, p.mids(x0), 0.0, 0.0, 0.0)
    measured = p.R0.T @ probe.direction_base()
    u = _taught_tool_axis(p, measured, tool_axis_flange, warnings)
    widths = _check_widths(p, warnings)
    dev_vec, per = _teach(p, x0, t, u)
    _check_heights_above_plane(p, float(dev_vec[2]))
    res_vec = per - dev_vec[[1, 0]][None, :]
    noise, source, widen = _device_noise(
        noise_in, res_vec, probe, given_axis=tool_axis_flange is not None, warnings=warnings
    )
    sigma = np.zeros(3)
    if noise > 0:

        def outputs(x: FloatArray) -> FloatArray:
            uu = u
            if tool_axis_flange is None:
                uu = p.R0.T @ _fit_line(p, p.mids(x), 0.0, 0.0, 0.0).direction_base()
            return _teach(p, x, t, uu)[0]

        sigma = widen * linear_sigma(outputs, x0, np.full(x0.size, noise))
    device = LaserDevice(
        beam_a_y_mm=float(dev_vec[0]), beam_b_x_mm=float(dev_vec[1]), plane_z_mm=float(dev_vec[2])
    )
    fit = DeviceFit(
        residuals_mm=tuple(float(r) for r in np.linalg.norm(res_vec, axis=1)),
        sigma_mm=(float(sigma[0]), float(sigma[1]), float(sigma[2])),
        sigma_source=source,
        axis_direction_flange=u,
        widths_mm=tuple(float(w) for w in widths),
        warnings=tuple(warnings),
    )
    return device, fit


def _taught_tool_axis(
    p: _Parsed, measured: FloatArray, tool_axis_flange: ArrayLike | None, warnings: list[str]
) -> FloatArray:
    """The trusted tool's axis (flange frame, unit): given, or the one the sweeps measured;
    warns when the two disagree, refuses an axis that does not point down through the beams."""
    if tool_axis_flange is None:
        u = measured
    else:
        u = check_finite(tool_axis_flange, loc=("teach", "tool_axis_flange"))
        norm = float(np.linalg.norm(u)) if u.shape == (3,) else 0.0
        if norm < 1e-9:
            raise InvalidInput(
                "invalid-options",
                "tool_axis_flange must be a non-zero 3-vector",
                loc=("teach", "tool_axis_flange"),
            )
        u = u / norm
        off = float(np.degrees(np.arccos(np.clip(u @ measured, -1.0, 1.0))))
        if off > 1.0:
            warnings.append(
                f"the sweeps see the tool axis {off:.2f} deg from the trusted tool's axis: "
                "is the trusted tool bent or mounted differently?"
            )
    if abs(float(u[2])) < 0.5 or float((p.R0 @ u)[2]) >= 0.0:
        raise InvalidInput(
            "degenerate-poses",
            "the tool axis does not point down through the beam plane at this flange "
            "rotation: the laser method needs the tool pointing down",
            loc=("poses", 0, "rotation"),
        )
    return u


def _check_heights_above_plane(p: _Parsed, plane_z: float) -> None:
    """Refuse a sweep height at or below the beam plane the descent found."""
    for k, h in enumerate(p.heights):
        if h <= plane_z:
            raise InvalidInput(
                "invalid-sweep",
                f"at flange z {h:.2f} mm the flange is not above the beam plane found from "
                f"the descent (z = {plane_z:.2f} mm)",
                loc=("sweeps", p.groups[k][0], "break_mm"),
            )


def _device_noise(
    noise_in: float | None,
    res_vec: FloatArray,
    probe: _Line,
    *,
    given_axis: bool,
    warnings: list[str],
) -> tuple[float, SigmaEstimate, float]:
    """The trigger noise behind the device's sigma, its source and the Student's t widening:
    configured, else from the heights' scatter when they have degrees of freedom to spare."""
    K = res_vec.shape[0]
    if noise_in is not None:
        return noise_in, "configured", 1.0
    if K >= 2 and given_axis:
        # Given axis: each height estimates x_B, y_A independently: K - 1 dof per beam.
        noise = float(np.sqrt(2.0 * np.sum(res_vec**2) / (2 * (K - 1))))
        return noise, "residuals", _widening(2 * (K - 1))
    if K >= 3:
        res = probe.residuals()
        noise = float(np.sqrt(2.0 * np.sum(probe.weights * res**2) / (2 * (K - 2))))
        return noise, "residuals", _widening(2 * (K - 2))
    warnings.append("no trigger noise given: the device's uncertainty was not estimated")
    return 0.0, "none", 1.0
