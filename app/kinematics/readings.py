"""Other readings of the same pose numbers: the unit and convention mix-ups seen in the field.

A reading is a pose format with the length and angle units its numbers are taken in. The
mix-ups a cell PC makes are other readings of the same numbers: metres sent as millimetres
(or the other way round), radians as degrees, a quaternion in the other component order, a
pendant's RPY view sent as a `ur_rotvec` rotation vector, `kuka_abc`'s A B C (about Z, Y, X)
sent as `fanuc_wpr`'s W P R (about X, Y, Z) or back, which is also the intrinsic/extrinsic
confusion of one Euler sequence. Formats are only exchanged for formats of the same arity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from app.kinematics.poses import WPR_FORMATS, PoseUnits, resolve_units
from app.words import Angle, Length, PoseFormat

#: Formats whose numbers may be confused with each other: same arity, same layout of x y z.
_SAME_ARITY: dict[str, tuple[PoseFormat, ...]] = {
    "matrix": ("matrix",),
    "xyz_wxyz": ("xyz_wxyz", "xyz_xyzw"),
    "xyz_xyzw": ("xyz_xyzw", "xyz_wxyz"),
    "kuka_abc": ("kuka_abc", "fanuc_wpr", "ur_rotvec"),
    "ur_rotvec": ("ur_rotvec", "fanuc_wpr", "kuka_abc"),
    "joints": ("joints",),
    **{fmt: (fmt, "kuka_abc", "ur_rotvec") for fmt in WPR_FORMATS},
}
#: Formats with angles among their numbers (the others have none, or quaternions).
_HAS_ANGLES = frozenset({"kuka_abc", "ur_rotvec", "joints", *WPR_FORMATS})
#: Formats with lengths among their numbers.
_HAS_LENGTHS = frozenset(set(_SAME_ARITY) - {"joints"})
#: No robot's flange works within this distance (mm) of its own base origin, which lies
#: inside the base: every touch that close means the lengths were not millimetres.
NEAR_BASE_MM = 20.0


@dataclass(frozen=True)
class Reading:
    """A pose format and the units its numbers are read in."""

    format: PoseFormat
    length: Length
    angle: Angle

    @classmethod
    def of(cls, fmt: PoseFormat, units: PoseUnits) -> Reading:
        return cls(fmt, units.length, units.angle)

    def changes_from(self, other: Reading) -> int:
        """How many of format, length unit and angle unit differ (those that matter)."""
        changes = int(self.format != other.format)
        if self.format in _HAS_LENGTHS:
            changes += int(self.length != other.length)
        if self.format in _HAS_ANGLES:
            changes += int(self.angle != other.angle)
        return changes

    def describe(self) -> str:
        """E.g. "kuka_abc in mm and deg", "xyz_xyzw in m"."""
        return f"{self.format} in {' and '.join(self.units().values())}"

    def units(self) -> dict[str, str]:
        """The units of the numbers this format has: no angle unit for a quaternion or a
        matrix (it would suggest the angles mattered), no length unit for joint angles."""
        units: dict[str, str] = {}
        if self.format in _HAS_LENGTHS:
            units["length"] = self.length
        if self.format in _HAS_ANGLES:
            units["angle"] = self.angle
        return units

    def as_request(self) -> dict[str, object]:
        """The `format` and `units` fields a client resends to read its numbers this way."""
        return {"format": self.format, "units": self.units()}


def given_reading(fmt: PoseFormat, units: dict[str, str] | None) -> Reading:
    """The reading a submission asks for: its format with the units resolved."""
    return Reading.of(fmt, resolve_units(fmt, units))


def other_readings(given: Reading) -> list[Reading]:
    """Every other reading of the same numbers, fewest changes first, the given one excluded.

    Units that a format's numbers do not have (angles of a quaternion, lengths of joint
    angles) stay as given, so that no two readings in the list read the numbers alike.
    """
    out: list[Reading] = []
    for fmt in _SAME_ARITY[given.format]:
        lengths: tuple[Length, ...] = ("mm", "m") if fmt in _HAS_LENGTHS else (given.length,)
        angles: tuple[Angle, ...] = ("deg", "rad") if fmt in _HAS_ANGLES else (given.angle,)
        for length in lengths:
            for angle in angles:
                reading = Reading(fmt, length, angle)
                if reading.changes_from(given) > 0:
                    out.append(reading)
    return sorted(out, key=lambda r: r.changes_from(given))


def flange_near_base(positions_mm: ArrayLike) -> bool:
    """Every flange position within NEAR_BASE_MM of the base origin: not millimetres."""
    f = np.asarray(positions_mm, dtype=np.float64).reshape(-1, 3)
    return f.shape[0] > 0 and float(np.linalg.norm(f, axis=1).max()) < NEAR_BASE_MM
