"""What a tool's guided session and a frame's share in their rows: how one is started."""

from __future__ import annotations

from collections.abc import Mapping

from sqlalchemy.orm import Session

from app.security.auth import Principal
from app.services.audit import writes as audit
from app.storage.models import GuidedSession


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
