"""What a tool's guided session and a frame's share in their rows: how one is started, and
the fields both show of it."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime
from typing import TypedDict

from sqlalchemy.orm import Session

from app.jsontypes import JsonObject
from app.schemas.common import Units
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.storage.models import GuidedSession
from app.words import AuditAction, PoseFormat, SessionMethod, SessionStatus


def start(
    session: Session,
    row: GuidedSession,
    *,
    actor: Principal,
    robot_id: str,
    about: Mapping[str, str] | None = None,
) -> None:
    """Insert a new session's row (open, no touches yet) with its session.create event."""
    row.poses, row.touches, row.status, row.created_by = [], [], "open", actor.name
    audit.add_created(
        session,
        row,
        actor=actor,
        action="session.create",
        resource_type="session",
        robot_id=robot_id,
        tool_id=row.tool_id,
        about=about,
        details={"method": row.method, "format": row.format},
    )


def event(
    session: Session,
    row: GuidedSession,
    action: AuditAction,
    actor: Principal,
    details: JsonObject,
    *,
    robot_id: str | None,
    about: Mapping[str, str] | None = None,
    version: int | None = None,
) -> None:
    """An audit event of a session (its touches' changes, its finish): the session the
    resource, with its tool and robot and the subject it calibrates (`about`)."""
    audit.record(
        session,
        actor=actor,
        action=action,
        resource_type="session",
        resource_id=row.id,
        robot_id=robot_id,
        tool_id=row.tool_id,
        about=about,
        version=version,
        details=details,
    )


class Shown(TypedDict):
    """The fields a tool's session (app.schemas.sessions.Session) and a frame's
    (app.schemas.frame_sessions.FrameSession) show alike, as their row holds them."""

    id: str
    tool_id: str
    status: SessionStatus
    method: SessionMethod
    format: PoseFormat
    units: Units | None
    created_at: datetime
    updated_at: datetime


def shown(row: GuidedSession) -> Shown:
    """What every session shows of its row (its touches and what they say are its kind's)."""
    return Shown(
        id=row.id,
        tool_id=row.tool_id,
        status=row.status,
        method=row.method,
        format=row.format,
        units=units_of(row),
        created_at=row.created_at,
        updated_at=row.updated_at,
    )


def units_of(row: GuidedSession) -> Units | None:
    """The units the session's poses are in, when it gave them."""
    return Units.model_validate(row.units) if row.units else None
