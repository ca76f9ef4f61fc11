"""A tool's drift trend (app.services.lifecycle.drift, with the tool's declaration): the TCP
position of its calibrated versions and the flange-frame deviations of its checks."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import ColumnElement
from sqlalchemy.orm import Session

from app.schemas.drift import ToolDrift
from app.services.lifecycle import drift
from app.services.lifecycle.drift import DRIFTING_WITHIN, Fitted, Point, fleet_drift
from app.services.lifecycle.versions import get_live
from app.services.tools.subject import TOOL

__all__ = ["DRIFTING_WITHIN", "Point", "crosses_by", "fleet_drift"]


def crosses_by(until: ColumnElement[datetime]) -> ColumnElement[bool]:
    """A tool's stored projection leaves check_mm by `until` (the `drifting` code)."""
    return drift.crosses_by(TOOL, until)


def refresh_drift(session: Session, tool: Fitted, *, pending_check: Point | None = None) -> None:
    """Fit a tool's trends and store them on the tool, in the caller's transaction
    (`pending_check`: a check recorded in this transaction)."""
    drift.store_drift(session, TOOL, tool.id, drift.fit_drift(session, TOOL, tool, pending_check))


def tool_drift(session: Session, tool_id: str) -> ToolDrift:
    """A live tool's drift trends (404 otherwise): the stored trend; computed (not stored) for
    a tool written before trends were."""
    tool = get_live(session, TOOL, tool_id)
    stored = tool.drift if tool.drift is not None else drift.fit_drift(session, TOOL, tool).drift
    return ToolDrift.model_validate(stored)
