"""The DH description of a serial arm: its links and convention, and the limits on them.

Apart from the forward kinematics (app.kinematics.dh) so that the makers' arms
(app/vendors/*/arms.py, the presets), which are such descriptions, and the spec reader, which
returns them, depend on it and not on each other; and so that declaring an arm loads no scipy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from app.jsontypes import JsonObject

Convention = Literal["dh", "mdh"]
CONVENTIONS: tuple[Convention, ...] = ("dh", "mdh")
#: Most joints an arm may have (7-axis arms plus a track or two).
MAX_LINKS = 12
#: Largest link length or offset accepted, mm.
MAX_LINK_MM = 10_000.0
#: Largest |angle| (deg) of a link's twist or joint offset.
MAX_LINK_DEG = 360.0


@dataclass(frozen=True)
class DHLink:
    """One row of a DH table: lengths mm, angles degrees."""

    a_mm: float
    alpha_deg: float
    d_mm: float
    theta_offset_deg: float = 0.0


@dataclass(frozen=True)
class Kinematics:
    """A serial arm: its DH convention and links, base to flange."""

    convention: Convention
    links: tuple[DHLink, ...]
    name: str | None = None

    @property
    def n_joints(self) -> int:
        """Number of revolute joints."""
        return len(self.links)

    def to_spec(self) -> JsonObject:
        """The API `kinematics` object that `kinematics_from_spec` reads back to this model."""
        return {
            "convention": self.convention,
            "links": [
                {
                    "a": link.a_mm,
                    "alpha": link.alpha_deg,
                    "d": link.d_mm,
                    "theta_offset": link.theta_offset_deg,
                }
                for link in self.links
            ],
        }
