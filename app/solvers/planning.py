"""Which touches to make: orientations that determine the TCP best, before the robot moves.

The N-point model R_i t + f_i = p is linear in (t, p), so with isotropic touch noise sigma
per axis the TCP covariance of N touches does not depend on t, p or the start orientation R0:

    Cov(t) = sigma^2 / N * (I - Rbar^T Rbar)^-1,   Rbar = mean_i(T_i),

where T_i = R0^T R_i is the touch relative to the start. The planner is **A-optimal**: it
minimises trace Cov(t), the expected squared TCP error. That is the figure an operator is
given (`predicted_sigma_mm` = sqrt of the trace, the RMS of the TCP error) and the one a
target is stated in; D-optimality (the determinant) would accept a design that is weak along
one axis as long as another is very strong, which leaves that axis of the TCP poorly known.

A touch is parametrised by tilt (the angle its tool axis, flange z, makes with the start's),
azimuth (the direction of that tilt) and spin (about the tool axis), within the reachable
cone: tilt <= max_tilt, |spin| <= max_spin. The optimiser (L-BFGS-B with box bounds, from a
fixed family of symmetric starting designs) is deterministic: the same input gives the same
plan. Guiding a session uses the same model to pick the next touch (`next_touch`): the one
that most reduces the largest remaining TCP variance given the touches already made.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray

MIN_TOUCHES = 4
MAX_TOUCHES = 30


@dataclass(frozen=True)
class Cone:
    """The reachable orientations around a start: tilt and |spin| limits in degrees."""

    max_tilt_deg: float
    max_spin_deg: float


@dataclass(frozen=True)
class Plan:
    """A touch set: tilt, azimuth, spin (deg) per touch, relative to the start orientation,
    and the predicted TCP covariance per unit touch noise (mm^2 per mm^2)."""

    tilt_deg: FloatArray
    azimuth_deg: FloatArray
    spin_deg: FloatArray
    unit_covariance: FloatArray

    def sigma_mm(self, touch_noise_mm: float) -> FloatArray:
        """Predicted 1-sigma per flange axis (mm) for the given touch noise."""
        out: FloatArray = touch_noise_mm * np.sqrt(np.diag(self.unit_covariance))
        return out

    def total_sigma_mm(self, touch_noise_mm: float) -> float:
        """sqrt(sx^2 + sy^2 + sz^2): the RMS of the TCP error (mm)."""
        return float(touch_noise_mm * np.sqrt(np.trace(self.unit_covariance)))


def relative_rotations(
    tilt_deg: FloatArray, azimuth_deg: FloatArray, spin_deg: FloatArray
) -> FloatArray:
    """T_i = Rot(a_i, tilt_i) Rz(spin_i) as matrices (N, 3, 3); a_i the azimuth's unit vector in
    the flange x-y plane. Same convention as app.kinematics.touchsets.cone_rotations."""
    th, az, sp = np.radians(tilt_deg), np.radians(azimuth_deg), np.radians(spin_deg)
    ax, ay = np.cos(az), np.sin(az)
    c, s = np.cos(th), np.sin(th)
    one_c = 1.0 - c
    tilt = np.empty((th.size, 3, 3))
    tilt[:, 0, 0] = c + ax * ax * one_c
    tilt[:, 0, 1] = ax * ay * one_c
    tilt[:, 0, 2] = ay * s
    tilt[:, 1, 0] = ax * ay * one_c
    tilt[:, 1, 1] = c + ay * ay * one_c
    tilt[:, 1, 2] = -ax * s
    tilt[:, 2, 0] = -ay * s
    tilt[:, 2, 1] = ax * s
    tilt[:, 2, 2] = c
    cs, ss = np.cos(sp), np.sin(sp)
    spin = np.zeros((th.size, 3, 3))
    spin[:, 0, 0], spin[:, 0, 1], spin[:, 1, 0], spin[:, 1, 1] = cs, -ss, ss, cs
    spin[:, 2, 2] = 1.0
    out: FloatArray = tilt @ spin
    return out


def unit_covariance(rotations: FloatArray) -> FloatArray:
    """Cov(t) / sigma^2 for touches with these orientations (N, 3, 3); inf when singular."""
    n = rotations.shape[0]
    mean = rotations.mean(axis=0)
    information = n * (np.eye(3) - mean.T @ mean)
    try:
        cov: FloatArray = np.linalg.inv(information)
    except np.linalg.LinAlgError:
        return np.full((3, 3), np.inf)
    if not np.all(np.isfinite(cov)) or np.min(np.linalg.eigvalsh(information)) <= 1e-12:
        return np.full((3, 3), np.inf)
    return cov


def _trace(x: FloatArray, n: int) -> float:
    rotations = relative_rotations(x[:n], x[n : 2 * n], x[2 * n :])
    mean = rotations.mean(axis=0)
    information = n * (np.eye(3) - mean.T @ mean)
    eig = np.linalg.eigvalsh(information)
    if eig[0] <= 1e-12:
        return 1e12
    return float(np.sum(1.0 / eig))


def _starts(n: int, cone: Cone) -> list[FloatArray]:
    """Symmetric starting designs: a ring at full tilt, spins alternating or spread."""
    k = np.arange(n)
    ring = 360.0 * k / n
    alternating = np.where(k % 2 == 0, cone.max_spin_deg, -cone.max_spin_deg)
    spread = np.linspace(-cone.max_spin_deg, cone.max_spin_deg, n)
    golden = (k * 137.50776405) % 360.0
    tilt_full = np.full(n, cone.max_tilt_deg)
    tilt_mixed = np.where(k % 3 == 0, 0.5 * cone.max_tilt_deg, cone.max_tilt_deg)
    designs = [
        (tilt_full, ring, alternating),
        (tilt_full, ring, spread),
        (tilt_full, golden, alternating),
        (tilt_mixed, ring, spread[::-1]),
        (tilt_full, ring, np.zeros(n)),
    ]
    return [np.concatenate(d) for d in designs]


def plan_touches(n: int, cone: Cone) -> Plan:
    """The A-optimal set of n touches within the cone (deterministic)."""
    from scipy.optimize import minimize  # a few hundred ms: imported by the first plan only

    bounds = (
        [(0.0, cone.max_tilt_deg)] * n
        + [(None, None)] * n
        + [(-cone.max_spin_deg, cone.max_spin_deg)] * n
    )
    best: FloatArray | None = None
    best_value = np.inf
    for x0 in _starts(n, cone):
        found = minimize(_trace, x0, args=(n,), method="L-BFGS-B", bounds=bounds)
        value = float(found.fun)
        if value < best_value - 1e-12:
            best, best_value = np.asarray(found.x, dtype=float), value
    assert best is not None
    tilt, azimuth, spin = best[:n], np.mod(best[n : 2 * n], 360.0), best[2 * n :]
    cov = unit_covariance(relative_rotations(tilt, azimuth, spin))
    return Plan(tilt, azimuth, spin, cov)


def smallest_plan(target_sigma_mm: float, touch_noise_mm: float, cone: Cone) -> Plan | None:
    """The plan with the fewest touches (MIN..MAX) whose total sigma reaches the target, or
    None when even MAX_TOUCHES cannot. The optimum's variance falls as 1/n (each touch adds
    the same information at best), so one plan predicts n; neighbours confirm the smallest."""
    cache: dict[int, Plan] = {}

    def plan(n: int) -> Plan:
        if n not in cache:
            cache[n] = plan_touches(n, cone)
        return cache[n]

    def reaches(n: int) -> bool:
        return plan(n).total_sigma_mm(touch_noise_mm) <= target_sigma_mm

    probe = 8
    ratio = plan(probe).total_sigma_mm(touch_noise_mm) / target_sigma_mm
    n = int(np.clip(np.ceil(probe * ratio**2), MIN_TOUCHES, MAX_TOUCHES))
    while not reaches(n):
        if n == MAX_TOUCHES:
            return None
        n += 1
    while n > MIN_TOUCHES and reaches(n - 1):
        n -= 1
    return plan(n)


def next_touch(done: FloatArray, cone: Cone) -> tuple[float, float, float]:
    """(tilt, azimuth, spin) in degrees of the touch that most reduces the largest TCP
    variance, given the touches made so far as orientations relative to the start (N, 3, 3).

    A grid over the cone (every 15 deg of azimuth, 3 tilts, 5 spins) is scored by the largest
    eigenvalue of the resulting TCP covariance; with too few touches to determine the TCP, a
    small ridge keeps the score finite and rewards the touch that opens the weakest direction.
    """
    tilts = np.linspace(cone.max_tilt_deg / 3.0, cone.max_tilt_deg, 3)
    azimuths = np.arange(0.0, 360.0, 15.0)
    spins = np.linspace(-cone.max_spin_deg, cone.max_spin_deg, 5)
    grid = np.array(np.meshgrid(tilts, azimuths, spins, indexing="ij")).reshape(3, -1)
    candidates = relative_rotations(grid[0], grid[1], grid[2])
    n = done.shape[0] + 1
    total = done.sum(axis=0)[None] + candidates  # (K, 3, 3)
    mean = total / n
    information = n * np.eye(3)[None] - np.einsum("kji,kjl->kil", mean, mean) * n
    information += 1e-9 * np.eye(3)[None]
    worst = 1.0 / np.linalg.eigvalsh(information)[:, 0]
    k = int(np.argmin(worst))
    return float(grid[0, k]), float(grid[1, k]), float(grid[2, k])


def tilt_lean_spin(first: FloatArray, other: FloatArray) -> tuple[float, float, float]:
    """How the orientation `other` (3x3) differs from `first`, in the words a person at the
    robot moves by (degrees): the tilt of the tool axis (flange z) from first's, the direction
    it leans toward in first's flange x-y plane (0 = +x, 90 = +y), and the spin about the tool
    axis (right-handed, -180..180).

    The spin is the twist of a swing-twist split of first^T other about z: the same split as
    `relative_rotations`' T = Rot(a, tilt) Rz(spin), whose swing axis a lies in the x-y plane."""
    relative = Rotation.from_matrix(first.T @ other)
    axis = relative.apply([0.0, 0.0, 1.0])
    tilt = float(np.degrees(np.arccos(np.clip(axis[2], -1.0, 1.0))))
    lean = float(np.mod(np.degrees(np.arctan2(axis[1], axis[0])), 360.0)) if tilt > 1e-9 else 0.0
    _, _, z, w = relative.as_quat()
    spin = float(np.degrees(2.0 * np.arctan2(z, w)))
    spin = (spin + 180.0) % 360.0 - 180.0
    return tilt, lean, spin
