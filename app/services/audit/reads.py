"""Reading the audit trail back: GET /v1/audit, newest first, by any of its filters.

Each filter is a seek in an index that ends in the event id (app.storage.models.AuditEvent), so a
page costs the same whatever the length of the trail. A page's cursor is bound to the
filters that made it: sent with other filters it would silently skip or repeat events, so
it is refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import InvalidInput
from app.helpers.pagination import paginate_newest_first
from app.schemas.audit import AuditEvent as AuditEventOut
from app.services.visible import in_scope
from app.storage.models import AuditEvent


@dataclass(frozen=True)
class AuditQuery:
    """The filters of GET /v1/audit (None: not filtered); `since` <= at < `until`."""

    tool_id: str | None = None
    frame_id: str | None = None
    robot_id: str | None = None
    action: str | None = None
    actor: str | None = None
    since: datetime | None = None
    until: datetime | None = None

    def key(self) -> str:
        """The filters as one string: what a cursor is bound to."""
        return repr(
            (
                self.tool_id,
                self.robot_id,
                self.action,
                self.actor,
                None if self.since is None else self.since.isoformat(),
                None if self.until is None else self.until.isoformat(),
                self.frame_id,
            )
        )


def list_events(
    session: Session, *, query: AuditQuery, limit: int, cursor: str | None
) -> tuple[list[AuditEventOut], str | None]:
    """One page of audit events, newest first; a key limited to cells sees the events of
    its cells' robots only."""
    if query.since is not None and query.until is not None and query.since > query.until:
        raise InvalidInput(
            "invalid-interval",
            f"since ({query.since.isoformat()}) is after until ({query.until.isoformat()}): "
            "give since <= until",
            loc=("query", "since"),
        )
    stmt = in_scope(session, select(AuditEvent), AuditEvent.robot_id)
    for column, value in (
        (AuditEvent.tool_id, query.tool_id),
        (AuditEvent.frame_id, query.frame_id),
        (AuditEvent.robot_id, query.robot_id),
        (AuditEvent.action, query.action),
        (AuditEvent.actor, query.actor),
    ):
        if value is not None:
            stmt = stmt.where(column == value)
    if query.since is not None:
        stmt = stmt.where(AuditEvent.at >= query.since)
    if query.until is not None:
        stmt = stmt.where(AuditEvent.at < query.until)
    rows, next_cursor = paginate_newest_first(
        session, stmt, id_col=AuditEvent.id, limit=limit, cursor=cursor, query=query.key()
    )
    return [event_out(r) for r in rows], next_cursor


def event_out(row: AuditEvent) -> AuditEventOut:
    """An audit row as GET /v1/audit shows it."""
    return AuditEventOut(
        id=str(row.id),
        at=row.at,
        action=row.action,
        actor=row.actor,
        request_id=row.request_id,
        resource_type=row.resource_type,
        resource_id=row.resource_id,
        robot_id=row.robot_id,
        tool_id=row.tool_id,
        frame_id=row.frame_id,
        version=row.version,
        detail=row.details,
    )
