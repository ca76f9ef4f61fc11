"""The one place that decides whether a result is within a tool's tolerance."""

from __future__ import annotations

from typing import Any

from app.schemas.tools import Tolerance


def effective_tolerance(stored: dict[str, Any] | None) -> dict[str, Any]:
    """A tool's tolerance with the API defaults filled in."""
    return Tolerance.model_validate(stored or {}).model_dump()


def grade(
    quality: dict[str, Any], tolerance: dict[str, Any], *, graded: bool
) -> tuple[str, list[str]]:
    """("accepted" | "out_of_tolerance", reasons) for a result's quality figures."""
    if not graded:
        return "accepted", []
    reasons: list[str] = []
    rms, worst = quality.get("rms_mm"), quality.get("max_mm")
    if rms is not None and rms > tolerance["max_rms_mm"]:
        reasons.append(
            f"rms residual {rms:.3f} mm exceeds the tool's max_rms_mm "
            f"{tolerance['max_rms_mm']:g} mm"
        )
    if worst is not None and worst > tolerance["max_residual_mm"]:
        reasons.append(
            f"largest residual {worst:.3f} mm exceeds the tool's max_residual_mm "
            f"{tolerance['max_residual_mm']:g} mm"
        )
    return ("out_of_tolerance" if reasons else "accepted"), reasons
