"""XYZ reference method and TCP check: one touch of a known point by a tool.

A trusted tool touches a fixed point once: r = R_1 t1 + f_1 registers the point in the base
frame. A new tool on the same flange touches it once: t2 = R_2^T (r - f_2). A check touch with
the active TCP t gives the deviation d = R t + f - r. Lengths mm, rotations flange -> base.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.noise_limits import MAX_TOUCH_NOISE_MM
from app.solvers.quality import SIGMA_CONFIGURED, Quality, make_quality
from app.solvers.validation import (
    MAX_ABS_MM,
    check_finite,
    check_positions_mm,
    check_rotation_matrices,
)


@dataclass(frozen=True)
class ReferenceResult:
    """TCP (3,) mm in the flange frame from one touch of a known point, with its quality."""

    tcp_mm: FloatArray
    quality: Quality


@dataclass(frozen=True)
class TcpDeviation:
    """How far the real tool tip is from where the active TCP puts it, at one touch of a
    reference point: actual minus expected, base (3,) and flange (3,) mm. In the flange frame
    it is the tool's shift, new TCP minus active TCP: +y means the tip moved along flange +Y.
    """

    deviation_base_mm: FloatArray
    deviation_flange_mm: FloatArray
    distance_mm: float


def reference_point_from_touch(
    *,
    tcp_mm: ArrayLike,
    tcp_covariance_mm2: ArrayLike | None,
    rotation: ArrayLike,
    position_mm: ArrayLike,
    touch_noise_mm: float | None,
) -> tuple[FloatArray, FloatArray]:
    """Point r = R t + f (3,) mm touched by a calibrated tool, and its covariance (3, 3) mm^2.

    Cov(r) = R Cov(t) R^T + touch_noise^2 I; a None covariance or touch noise adds nothing.
    """
    t = _vector(tcp_mm, "tcp_mm")
    cov_t = _covariance(tcp_covariance_mm2, "tcp_covariance_mm2")
    R, f = _pose(rotation, position_mm)
    s = _touch_noise(touch_noise_mm)
    r = R @ t + f
    cov_r = R @ cov_t @ R.T + s**2 * np.eye(3)
    return r, 0.5 * (cov_r + cov_r.T)


def solve_reference(
    *,
    reference_mm: ArrayLike,
    reference_covariance_mm2: ArrayLike | None,
    rotation: ArrayLike,
    position_mm: ArrayLike,
    touch_noise_mm: float | None,
) -> ReferenceResult:
    """New TCP t2 = R^T (r - f) (3,) mm from one touch of the reference point r (3,) mm.

    Cov(t2) = R^T (Cov(r) + touch_noise^2 I) R. One touch has no redundancy: the residual is 0
    and the uncertainty is entirely propagated; a warning says what it leaves out.
    """
    r = _vector(reference_mm, "reference_mm")
    cov_r = _covariance(reference_covariance_mm2, "reference_covariance_mm2")
    R, f = _pose(rotation, position_mm)
    s = _touch_noise(touch_noise_mm)
    t2 = R.T @ (r - f)
    if float(np.abs(t2).max()) > MAX_ABS_MM:
        raise InvalidInput(
            "out-of-range",
            f"the touch puts the TCP {float(np.linalg.norm(t2)):.6g} mm from the flange: the "
            "reference point or the pose is wrong",
            loc=("poses", 0, "position"),
        )
    cov_t = R.T @ (cov_r + s**2 * np.eye(3)) @ R
    warnings: list[str] = []
    if touch_noise_mm is None:
        warnings.append(
            "the tool's touch noise is unknown: the uncertainty covers only the reference "
            "point, not this touch; configure the touch noise for an honest figure"
        )
    if reference_covariance_mm2 is None:
        warnings.append("the reference point has no uncertainty on record: it is taken as exact")
    quality = make_quality(
        residuals_mm=np.zeros(1),
        tcp_covariance_mm2=cov_t,
        sigma_source=SIGMA_CONFIGURED,
        orientation_spread_deg=0.0,
        condition_number=1.0,
        warnings=tuple(warnings),
        dof=None,
    )
    return ReferenceResult(tcp_mm=t2, quality=quality)


def check_tcp(
    *,
    tcp_mm: ArrayLike,
    rotation: ArrayLike,
    position_mm: ArrayLike,
    reference_mm: ArrayLike,
) -> TcpDeviation:
    """Deviation d = r - (R t + f) at a touch of reference point r with active TCP t, mm.

    The tip touches r, so r = R t_real + f and d = R (t_real - t): in the flange frame,
    R^T d = t_real - t is how the tool moved since t was calibrated (new minus old).
    """
    t = _vector(tcp_mm, "tcp_mm")
    r = _vector(reference_mm, "reference_mm")
    R, f = _pose(rotation, position_mm)
    d = r - (R @ t + f)
    return TcpDeviation(
        deviation_base_mm=d,
        deviation_flange_mm=R.T @ d,
        distance_mm=float(np.linalg.norm(d)),
    )


def _vector(value: ArrayLike, name: str) -> FloatArray:
    arr = check_finite(value, loc=(name,))
    if arr.shape != (3,):
        raise InvalidInput(
            "invalid-pose", f"{name} must be 3 numbers (mm), got shape {arr.shape}", loc=(name,)
        )
    out: FloatArray = check_positions_mm(arr[None, :], loc=(name,))[0]
    return out


def _covariance(value: ArrayLike | None, name: str) -> FloatArray:
    if value is None:
        return np.zeros((3, 3))
    arr = check_finite(value, loc=(name,))
    if arr.shape != (3, 3):
        raise InvalidInput(
            "invalid-options",
            f"{name} must be a 3x3 matrix (mm^2), got shape {arr.shape}",
            loc=(name,),
        )
    scale = max(float(np.abs(arr).max()), 1e-300)
    if (
        float(np.abs(arr - arr.T).max()) > 1e-9 * scale
        or float(np.linalg.eigvalsh(0.5 * (arr + arr.T))[0]) < -1e-9 * scale
    ):
        raise InvalidInput(
            "invalid-options",
            f"{name} is not a covariance: it must be symmetric with no negative variance",
            loc=(name,),
        )
    return 0.5 * (arr + arr.T)


def _pose(rotation: ArrayLike, position_mm: ArrayLike) -> tuple[FloatArray, FloatArray]:
    R = check_rotation_matrices(np.asarray(rotation, dtype=np.float64)[None], loc=("poses",))[0]
    f = check_positions_mm(np.asarray(position_mm, dtype=np.float64).reshape(1, -1))[0]
    return R, f


def _touch_noise(value: float | None) -> float:
    if value is None:
        return 0.0
    v = float(value)
    if not (np.isfinite(v) and 0.0 <= v <= MAX_TOUCH_NOISE_MM):
        raise InvalidInput(
            "invalid-options",
            f"touch_noise_mm = {value!r} is not usable: it must be between 0 and "
            f"{MAX_TOUCH_NOISE_MM:g} mm",
            loc=("options", "touch_noise_mm"),
        )
    return v
