"""Re-registration after a move: the rigid shift that carries a frame's stored fiducials onto
where they are touched now (METHODS.md 7, issue 49).

A fixture unbolted and put back, or a robot bumped, moves every point taught in the frame by
one rigid transform S: x -> dR x + dt (base frame). The fiducials' stored positions
q_k = R0 n_k + o0 and the new touches p_k give S as the fit_points transform from q_k to p_k
(the same estimator, outlier test and correlated covariance); the corrected frame is S
composed with the old one: R' = dR R0, o' = dR o0 + dt.

Before any shift is computed, a touch far from the fiducial it names is refused: the wrong
point, or the wrong frame. Far means beyond `max_distance_mm` (the frame's largest allowed
correction and a margin), and the refusal says which stored fiducial the touch is nearest.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.frame.fit_points import fit_points
from app.solvers.frame.model import FrameEstimate

#: At least this many fiducials: three fix a rigid shift with no redundancy.
MIN_FIDUCIALS = 3


@dataclass(frozen=True)
class Shift:
    """The move found: dR (3, 3) and dt (3,) mm in the base frame, the fit behind it (its
    covariance over [dt mm, small rotations rad about the base axes after dR]), and each
    fiducial's deviation in the frame's axes (K, 3) mm."""

    rotation: FloatArray
    translation_mm: FloatArray
    fit: FrameEstimate
    deviations_mm: FloatArray

    @property
    def distances_mm(self) -> FloatArray:
        """How far each fiducial moved, mm."""
        out: FloatArray = np.linalg.norm(self.deviations_mm, axis=1)
        return out

    @property
    def angle_deg(self) -> float:
        """The shift's rotation angle, deg."""
        return float(np.degrees(Rotation.from_matrix(self.rotation).magnitude()))

    @property
    def axis(self) -> FloatArray:
        """The unit axis of the shift's rotation in the base frame (z when it is none)."""
        rotvec = Rotation.from_matrix(self.rotation).as_rotvec()
        norm = float(np.linalg.norm(rotvec))
        out: FloatArray = rotvec / norm if norm > 1e-12 else np.array([0.0, 0.0, 1.0])
        return out

    def moved(self, rotation: FloatArray, origin_mm: FloatArray) -> tuple[FloatArray, FloatArray]:
        """A frame (R, o) carried by the shift: (dR R, dR o + dt)."""
        return self.rotation @ rotation, self.rotation @ origin_mm + self.translation_mm


def check_near(
    names: Sequence[str],
    stored_mm: FloatArray,
    stored_names: Sequence[str],
    points_mm: FloatArray,
    max_distance_mm: float,
) -> None:
    """Refuse a touch farther than `max_distance_mm` from the fiducial it names, naming the
    stored fiducial it is nearest (loc ("touches", i, "fiducial"))."""
    known = list(stored_names)
    for i, (name, p) in enumerate(zip(names, points_mm, strict=True)):
        if name not in known:
            raise InvalidInput(
                "unknown-reference",
                f"touch {i + 1} names fiducial {name!r}, which this frame does not have: its "
                f"fiducials are {', '.join(repr(n) for n in known)}",
                loc=("touches", i, "fiducial"),
            )
        distance = float(np.linalg.norm(p - stored_mm[known.index(name)]))
        if distance <= max_distance_mm:
            continue
        gaps = np.linalg.norm(stored_mm - p, axis=1)
        nearest = int(np.argmin(gaps))
        where = (
            f"it is {gaps[nearest]:.1f} mm from fiducial {stored_names[nearest]!r}: touch "
            f"{name!r} again, or name the fiducial touched"
            if gaps[nearest] <= max_distance_mm
            else "no stored fiducial of this frame is near it: a wrong point, or another frame"
        )
        raise InvalidInput(
            "unknown-reference",
            f"touch {i + 1} is {distance:.1f} mm from fiducial {name!r}, more than the "
            f"{max_distance_mm:g} mm a move may shift it; {where}",
            loc=("touches", i, "fiducial"),
            context={"distance_mm": distance},
        )


def shift_from_fiducials(
    stored_mm: ArrayLike,
    frame_rotation: ArrayLike,
    points_mm: ArrayLike,
    rotations: ArrayLike,
    tcp_covariance_mm2: ArrayLike,
    *,
    touch_noise_mm: float | None,
) -> Shift:
    """The shift from the fiducials' stored base positions (K, 3) mm to the touched points
    (K, 3) mm (flange rotations (K, 3, 3), the pointer TCP's covariance), with each
    fiducial's deviation in the axes of the frame (rotation (3, 3) frame -> base)."""
    q = np.asarray(stored_mm, dtype=np.float64)
    p = np.asarray(points_mm, dtype=np.float64)
    if q.shape[0] < MIN_FIDUCIALS:
        raise InvalidInput(
            "too-few-poses",
            f"a re-check after a move needs at least {MIN_FIDUCIALS} fiducials, not on one "
            f"line; got {q.shape[0]}",
            loc=("touches",),
        )
    fit = fit_points(q, p, rotations, tcp_covariance_mm2, touch_noise_mm=touch_noise_mm)
    R0 = np.asarray(frame_rotation, dtype=np.float64)
    deviations = (p - q) @ R0
    return Shift(fit.rotation, fit.origin_mm, fit, deviations)
