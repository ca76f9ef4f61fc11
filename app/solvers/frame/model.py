"""What every frame method shares: touched points, their correlated covariance, the estimate.

A frame touch is a flange pose (R_i, f_i) of the robot holding a pointer tool whose TCP t
(mm, flange frame) is calibrated: the touched point in the base frame is p_i = R_i t + f_i.
The pointer's TCP error dt is the same at every touch, and enters each point turned by that
touch's flange rotation, so the points are correlated (METHODS.md section 7):

    Cov(p_i, p_j) = delta_ij sigma^2 I + R_i Cov(t) R_j^T

A frame is (R, o): R (3, 3) frame -> base, o (3,) mm in the base frame. Its covariance is
(6, 6) over [delta o (mm, base axes), delta theta (rad, small rotations about the frame's own
axes, R' = R exp([delta theta]x))].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.solvers.distributions import chi2_ppf, f_ppf
from app.solvers.npoint.model import BoolArray
from app.solvers.quality import SigmaSource

#: Probability content of the intervals and of the worst-point radius the summary gives.
PROBABILITY_95 = 0.95


@dataclass(frozen=True)
class Pointer:
    """The pointer tool's TCP (3,) mm in the flange frame and its covariance (3, 3) mm^2."""

    tcp_mm: FloatArray
    tcp_covariance_mm2: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))

    @staticmethod
    def of(tcp_mm: ArrayLike, tcp_sigma_mm: ArrayLike | None = None) -> Pointer:
        """A pointer from its TCP and, optionally, its per-axis 1-sigma (independent axes)."""
        sigma = np.zeros(3) if tcp_sigma_mm is None else np.asarray(tcp_sigma_mm, dtype=float)
        return Pointer(np.asarray(tcp_mm, dtype=np.float64), np.diag(sigma**2))


def touch_points(rotations: FloatArray, positions_mm: FloatArray, tcp_mm: FloatArray) -> FloatArray:
    """The touched points (N, 3) mm in the base frame: R_i t + f_i."""
    points: FloatArray = np.einsum("nij,j->ni", rotations, tcp_mm) + positions_mm
    return points


def point_covariance(
    rotations: FloatArray, touch_noise_mm: float, tcp_covariance_mm2: FloatArray
) -> FloatArray:
    """The (3N, 3N) covariance of the stacked touched points, the pointer's error shared."""
    n = rotations.shape[0]
    B = rotations.reshape(3 * n, 3)  # the rows of R_i stacked: p_i's sensitivity to dt
    cov: FloatArray = touch_noise_mm**2 * np.eye(3 * n) + B @ tcp_covariance_mm2 @ B.T
    return cov


def interval_scale(dof: int | None, dims: int = 1) -> float:
    """k for a 95 % region of `dims` dimensions: known noise (dof None) chi2, estimated F."""
    if dof is None:
        return math.sqrt(chi2_ppf(PROBABILITY_95, dims))
    return math.sqrt(dims * f_ppf(PROBABILITY_95, dims, max(dof, 1)))


@dataclass(frozen=True)
class FrameEstimate:
    """A calibrated frame with its quality; lengths mm, angles as stated on each field."""

    rotation: FloatArray  # (3, 3) frame -> base
    origin_mm: FloatArray  # (3,) base frame
    covariance: FloatArray  # (6, 6) over [origin mm (base axes), rotation rad (frame axes)]
    points_mm: FloatArray  # (N, 3) each touch's point, base frame
    nominal_mm: FloatArray  # (N, 3) each touch's point in the frame (the fiducials)
    residuals_mm: FloatArray  # (N,) |R n_i + o - p_i|
    used: BoolArray  # (N,) bool: touches the fit used (False: an outlier set aside)
    touch_noise_mm: float  # the 1-sigma behind the covariance
    sigma_source: SigmaSource
    dof: int | None  # None: the touch noise was configured
    warnings: tuple[str, ...] = ()

    @property
    def quaternion_wxyz(self) -> FloatArray:
        """The frame's rotation as a unit quaternion, w first (tcpcal's order), w >= 0."""
        x, y, z, w = Rotation.from_matrix(self.rotation).as_quat()
        q = np.array([w, x, y, z])
        return q if w >= 0 else -q

    @property
    def position_sigma_mm(self) -> FloatArray:
        """1-sigma of the origin per base axis, mm."""
        return np.sqrt(np.clip(np.diag(self.covariance)[:3], 0.0, None))

    @property
    def angle_sigma_deg(self) -> FloatArray:
        """1-sigma of the small rotations about the frame's x, y, z axes, deg."""
        return np.degrees(np.sqrt(np.clip(np.diag(self.covariance)[3:], 0.0, None)))

    @property
    def outliers(self) -> tuple[int, ...]:
        """0-based indexes of the touches set aside."""
        return tuple(int(i) for i in np.flatnonzero(~np.asarray(self.used, dtype=bool)))

    def point_covariance_mm2(self, nominal_mm: ArrayLike) -> FloatArray:
        """Covariance (3, 3) mm^2 in base axes of the frame point with frame coordinates n."""
        n = np.asarray(nominal_mm, dtype=np.float64)
        J = np.hstack([np.eye(3), -self.rotation @ skew(n)])
        cov: FloatArray = J @ self.covariance @ J.T
        return cov

    def point_error_95_mm(self, nominal_mm: ArrayLike) -> float:
        """Radius within which the point n lies with 95 % (the 3-D ellipsoid's longest axis)."""
        largest = float(np.linalg.eigvalsh(self.point_covariance_mm2(nominal_mm))[-1])
        return interval_scale(self.dof, 3) * math.sqrt(max(largest, 0.0))

    def extent(self) -> tuple[float, float]:
        """(r, e): the farthest touched point's distance r from the origin (mm) and the worst
        95 % position error e (mm) over the box the touched points span in the frame."""
        n = self.nominal_mm[np.asarray(self.used, dtype=bool)]
        lo, hi = n.min(axis=0), n.max(axis=0)
        corners = np.array([[(lo, hi)[(k >> a) & 1][a] for a in range(3)] for k in range(8)])
        candidates = np.vstack([n, corners])
        worst = max(self.point_error_95_mm(c) for c in candidates)
        return float(np.linalg.norm(n, axis=1).max()), worst

    def in_frame(self, points_mm: ArrayLike) -> FloatArray:
        """Base-frame points (N, 3) expressed in this frame: R^T (p - o)."""
        p = np.asarray(points_mm, dtype=np.float64)
        out: FloatArray = (p - self.origin_mm) @ self.rotation
        return out


def skew(v: ArrayLike) -> FloatArray:
    """[v]x, the (3, 3) matrix of the cross product with v; for vectors (..., 3), one such
    matrix each (..., 3, 3)."""
    a = np.asarray(v, dtype=np.float64)
    out: FloatArray = np.zeros((*a.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -a[..., 2], a[..., 1], -a[..., 0]
    out -= np.swapaxes(out, -1, -2)
    return out
