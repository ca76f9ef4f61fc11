"""The audit trail: one row per write, with who and when."""

from __future__ import annotations

from sqlalchemy.orm import Session

from app.auth import Principal
from app.jsontypes import JsonObject
from app.models import AuditEvent


def record(
    session: Session,
    *,
    actor: Principal,
    action: str,
    resource_type: str,
    resource_id: str,
    robot_id: str | None = None,
    tool_id: str | None = None,
    details: JsonObject | None = None,
) -> None:
    """Append an audit event to the current transaction."""
    session.add(
        AuditEvent(
            actor=actor.name,
            api_key_id=actor.key_id,
            action=action,
            resource_type=resource_type,
            resource_id=resource_id,
            robot_id=robot_id,
            tool_id=tool_id,
            details=details,
        )
    )
