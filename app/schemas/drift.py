"""A tool's drift trend (docs/drift.md): how fast its TCP moves, and when it is projected out
of check_mm."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from app.schemas.common import Timestamp

DriftBasis = Literal["checks", "versions"]


class SeriesTrend(BaseModel):
    """A robust straight line through one series, per axis x, y, z (mm/month, 30.44 days)."""

    n: int = Field(description="points fitted (the newest, at most 60)")
    first_at: Timestamp = Field(description="the first point's time")
    last_at: Timestamp = Field(description="the last point's time")
    t0_at: Timestamp = Field(description="the time the level is given at (the mean time)")
    level_mm: list[float] = Field(description="the line's value at t0_at, x y z (mm)")
    rate_mm_per_month: list[float] = Field(description="x y z rates")
    sigma_mm_per_month: list[float] = Field(description="their standard errors")
    low_mm_per_month: list[float] = Field(description="95 % interval, low ends")
    high_mm_per_month: list[float] = Field(description="95 % interval, high ends")
    speed_mm_per_month: float = Field(description="length of the rate vector")
    speed_sigma_mm_per_month: float = Field(description="its standard error")
    outliers: int = Field(description="points more than 3 noise scales off the line")
    crosses_check_at: Timestamp | None = Field(
        description="when the 95 % lower bound of the projected deviation from the active TCP "
        "reaches check_mm (within 2 years), or null"
    )


class FleetDrift(BaseModel):
    """The drift a fleet row shows: the checks' trend when the active version has three checks
    over a day or more, else the TCP's over the versions."""

    basis: DriftBasis = Field(description="the series the figures come from")
    rate_mm_per_month: float = Field(description="how fast the TCP moves (any direction)")
    sigma_mm_per_month: float = Field(description="its standard error (mm/month)")
    crosses_check_at: Timestamp | None = Field(
        description="when it is projected out of check_mm at 95 % confidence, or null"
    )


class ToolDrift(BaseModel):
    """A tool's drift: the TCP position over its calibrated versions (accepted, not manual)
    and the deviations of the active version's checks over time; null where fewer than three
    points over a day exist."""

    tool_id: str = Field(description="the tool")
    active_version: int | None = Field(description="the version the checks' series measured")
    check_mm: float = Field(description="the limit the projections are compared with (mm)")
    versions: SeriesTrend | None = Field(
        description="the TCP position over the accepted, measured versions"
    )
    checks: SeriesTrend | None = Field(
        description="the flange-frame deviations of the active version's checks"
    )
    fleet: FleetDrift | None = Field(description="what the fleet row shows")
