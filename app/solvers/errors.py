"""The one exception the pure libraries (solvers, kinematics, exports) raise for bad input.

It carries a machine-readable `kind` (the last segment of the problem type the HTTP layer
answers with, e.g. "degenerate-poses"), a sentence a technician understands, and where known
the location of the offending value (e.g. ("poses", 3, "rotation")). It knows nothing of HTTP.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

#: Every kind a library may raise, with a short title for the problem document.
KINDS: dict[str, str] = {
    "too-few-poses": "Too few poses",
    "repeated-poses": "Repeated poses",
    "degenerate-poses": "Degenerate poses",
    "insufficient-spread": "Orientation spread too small",
    "invalid-rotation": "Invalid rotation",
    "non-finite": "Non-finite value",
    "out-of-range": "Value out of range",
    "invalid-pose": "Invalid pose",
    "invalid-options": "Invalid options",
    "missing-kinematics": "Robot has no kinematics",
    "orientation-changed": "Orientation changed during a translation",
    "invalid-direction": "Invalid direction",
    "invalid-sweep": "Invalid laser sweep",
    "missing-load": "Tool load missing",
    "unknown-format": "Unknown format",
    "unsupported": "Not supported",
}


class SolveError(ValueError):
    """Input that a pure library cannot use, with the reason and where it is."""

    def __init__(
        self,
        kind: str,
        detail: str,
        *,
        loc: Sequence[str | int] = (),
        extra: Mapping[str, Any] | None = None,
    ) -> None:
        if kind not in KINDS:
            raise ValueError(f"unknown SolveError kind {kind!r}")
        super().__init__(detail)
        self.kind = kind
        self.detail = detail
        self.loc: tuple[str | int, ...] = tuple(loc)
        self.extra: dict[str, Any] = dict(extra or {})

    @property
    def title(self) -> str:
        """Short human title of this kind."""
        return KINDS[self.kind]

    def __repr__(self) -> str:
        return f"SolveError({self.kind!r}, {self.detail!r}, loc={self.loc!r})"
