"""Frames a robot works in (bases, work objects, user frames) and stationary tools, from
touches of a pointer tool whose TCP is calibrated (METHODS.md section 7).

- `model`: the touched points p_i = R_i t + f_i, their covariance with the pointer's TCP
  error shared by every touch, and `FrameEstimate` (the frame, its 6x6 covariance, the
  fiducials, the worst 95 % position error over the touched extent).
- `construction`: `three_point` (by maker convention) and `four_point`, exact constructions.
- `fit_points`: the weighted rigid fit of nominal points, robust to one bad touch in five.
- `fixed_tip`: a stationary tool's tip by the N-point pivot fit.
- `shift`: re-registration after a move, the rigid shift from stored fiducials touched again.
"""

from __future__ import annotations

from app.solvers.frame.construction import (
    CONVENTIONS,
    FOUR_POINT,
    MAX_ANGLE_SIGMA_DEG,
    THREE_POINT,
    Construction,
    construct,
)
from app.solvers.frame.fit_points import fit_points as fit_points
from app.solvers.frame.fixed_tip import FixedTip, fixed_tip
from app.solvers.frame.model import (
    FrameEstimate,
    Pointer,
    interval_scale,
    point_covariance,
    touch_points,
)

# fit_points is re-exported by `as` above, not listed here: its name is a method's word too,
# which app/words.py alone spells (tests/test_one_definition.py).
__all__ = [
    "CONVENTIONS",
    "FOUR_POINT",
    "MAX_ANGLE_SIGMA_DEG",
    "THREE_POINT",
    "Construction",
    "FixedTip",
    "FrameEstimate",
    "Pointer",
    "construct",
    "fixed_tip",
    "interval_scale",
    "point_covariance",
    "touch_points",
]
