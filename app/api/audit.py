"""HTTP for the audit trail (admin): every change, newest first, by filter."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Query
from pydantic import AwareDatetime

from app.api.deps import AdminKey, SessionDep
from app.api.params import Cursor, Limit, known_query_only
from app.api.shared import page
from app.helpers.pagination import DEFAULT_LIMIT
from app.schemas.audit import AuditEvent
from app.schemas.common import ID_PATTERN, NO_CONTROL_PATTERN, Page
from app.services.audit import reads as trail

router = APIRouter(tags=["audit"])

Moment = Annotated[
    AwareDatetime | None,
    Query(description="RFC 3339 with a time zone, e.g. 2026-11-24T06:00:00Z"),
]


@router.get("/v1/audit", response_model=Page[AuditEvent], dependencies=[Depends(known_query_only)])
def list_audit(
    session: SessionDep,
    key: AdminKey,
    tool_id: Annotated[str | None, Query(pattern=ID_PATTERN)] = None,
    frame_id: Annotated[str | None, Query(pattern=ID_PATTERN)] = None,
    robot_id: Annotated[str | None, Query(pattern=ID_PATTERN)] = None,
    action: Annotated[
        str | None,
        Query(
            min_length=1,
            max_length=60,
            pattern=NO_CONTROL_PATTERN,
            description="e.g. version.activate",
        ),
    ] = None,
    actor: Annotated[
        str | None,
        Query(min_length=1, max_length=200, pattern=NO_CONTROL_PATTERN, description="key name"),
    ] = None,
    since: Annotated[Moment, Query(description="events at or after this time")] = None,
    until: Annotated[Moment, Query(description="events before this time")] = None,
    limit: Limit = DEFAULT_LIMIT,
    cursor: Cursor = None,
) -> Page[AuditEvent]:
    """Every change (robots, tools, frames and their tolerances, calibrations, versions,
    activations, checks, keys, guided sessions, reference points, laser devices), newest
    first, with who made it, when, in which request (`request_id`, as in the access log)
    and what changed. Unknown query parameters and a cursor from another query (other
    filters) are refused with 422. A key limited to cells sees its cells' events only;
    `frame_id` filters a frame's events as `tool_id` a tool's."""
    query = trail.AuditQuery(
        tool_id=tool_id,
        frame_id=frame_id,
        robot_id=robot_id,
        action=action,
        actor=actor,
        since=since,
        until=until,
    )
    items, next_cursor = trail.list_events(session, query=query, limit=limit, cursor=cursor)
    return page(AuditEvent, items, next_cursor)
