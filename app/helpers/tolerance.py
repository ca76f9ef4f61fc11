"""The one place that decides whether a result is within a tool's tolerance."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

from app.schemas.tools import Tolerance
from app.words import Status


def effective_tolerance(stored: Mapping[str, object] | Tolerance | None) -> Tolerance:
    """A tool's tolerance with the API defaults filled in."""
    if isinstance(stored, Tolerance):
        return stored
    return Tolerance.model_validate(stored or {})


class Residuals(Protocol):
    """What grading reads of a result's quality (a tool calibration's, a frame's)."""

    @property
    def rms_mm(self) -> float | None: ...
    @property
    def max_mm(self) -> float | None: ...


class ResidualLimits(Protocol):
    """What grading reads of a tolerance (a tool's, a frame's)."""

    @property
    def max_rms_mm(self) -> float: ...
    @property
    def max_residual_mm(self) -> float: ...


def grade(
    quality: Residuals, tolerance: ResidualLimits, *, graded: bool, of: str = "tool"
) -> tuple[Status, list[str]]:
    """("accepted" | "out_of_tolerance", reasons) for a result's quality figures, against the
    tolerance of `of` (the subject's kind, as the reasons name it)."""
    if not graded:
        return "accepted", []
    reasons: list[str] = []
    if quality.rms_mm is not None and quality.rms_mm > tolerance.max_rms_mm:
        reasons.append(
            f"rms residual {quality.rms_mm:.3f} mm exceeds the {of}'s max_rms_mm "
            f"{tolerance.max_rms_mm:g} mm"
        )
    if quality.max_mm is not None and quality.max_mm > tolerance.max_residual_mm:
        reasons.append(
            f"largest residual {quality.max_mm:.3f} mm exceeds the {of}'s max_residual_mm "
            f"{tolerance.max_residual_mm:g} mm"
        )
    return ("out_of_tolerance" if reasons else "accepted"), reasons
