"""The publisher's side of the database: undelivered outbox rows, the current state of the
tools they concern, marking rows delivered and pruning them.

A tool's state is the document GET /v1/tools/{tool_id}/tcp serves, built by the same service
(`app.services.tools.versions.served_tcp`), with the active version's `status` (accepted or
out_of_tolerance) and `activation` (how it went live: kind, reason, at, by; the plant's
reading, app.services.fleet.plant) added, read when it is published, never a snapshot taken when
the change was made: whatever the order in which redelivered rows arrive, the last state a
sink receives of a tool is its current one.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Sequence
from datetime import datetime, timedelta

from sqlalchemy import Engine, delete, or_, select, update
from sqlalchemy.orm import Session

from app.errors import Archived, NoActiveVersion, NotFound
from app.jsontypes import JsonObject
from app.publish.sink import Message, PublishedTool
from app.services.fleet.plant import activations_of, active_statuses
from app.services.tools.versions import served_tcp
from app.storage.models import OutboxMessage, Robot, Tool, utcnow


def undelivered(session: Session, *, limit: int) -> list[Message]:
    """The oldest undelivered rows, in id order (commit order per tool)."""
    rows = session.scalars(
        select(OutboxMessage)
        .where(OutboxMessage.delivered_at.is_(None))
        .order_by(OutboxMessage.id)
        .limit(limit)
    )
    return [Message(r.id, r.action, r.robot_id, r.tool_id, r.payload) for r in rows]


def tools_concerned(session: Session, messages: Sequence[Message]) -> list[str]:
    """The tools whose state follows the messages: each message's tool, and for a message
    about a robot alone (an update, an archive) the robot's live tools and those archived
    with it. In order of first mention."""
    ordered: dict[str, None] = {}
    robots: list[str] = []
    for message in messages:
        if message.tool_id is not None:
            ordered[message.tool_id] = None
        elif message.robot_id is not None:
            robots.append(message.robot_id)
    if robots:
        stmt = (
            select(Tool.id)
            .join(Robot, Robot.id == Tool.robot_id)
            .where(
                Tool.robot_id.in_(robots),
                or_(Tool.archived_at.is_(None), Tool.archived_at == Robot.archived_at),
            )
            .order_by(Tool.created_at, Tool.id)
        )
        for tool_id in session.scalars(stmt):
            ordered[tool_id] = None
    return list(ordered)


def snapshot(session: Session) -> None:
    """Make the rest of `session`'s transaction read the database as of one moment.

    A tool's document (its active version) and that version's status and activation are read
    by separate statements; in PostgreSQL's default READ COMMITTED each statement sees what was
    committed when it began, so an activation committed between them published an
    out-of-tolerance TCP as `accepted` (a fresh clone's .ci/run, test_mqtt.py:377).
    REPEATABLE READ reads them all from the transaction's first snapshot. Call it first.
    """
    if session.get_bind().dialect.name == "postgresql":
        session.connection(execution_options={"isolation_level": "REPEATABLE READ"})


def states(session: Session, tool_ids: Iterable[str]) -> list[PublishedTool]:
    """The current state of each tool (unknown ids are left out)."""
    wanted = list(tool_ids)
    if not wanted:
        return []
    names = {
        row.id: row
        for row in session.execute(
            select(Tool.id, Tool.robot_id, Tool.name, Tool.archived_at, Robot.name.label("robot"))
            .join(Robot, Robot.id == Tool.robot_id)
            .where(Tool.id.in_(wanted))
        )
    }
    statuses = active_statuses(session, wanted)
    activations = activations_of(session, wanted)
    found = []
    for tool_id in wanted:
        row = names.get(tool_id)
        if row is None:
            continue
        body = document(session, tool_id)
        if body is not None:
            activation = activations.get(tool_id)
            body["status"] = statuses.get(tool_id)
            body["activation"] = None if activation is None else activation.model_dump(mode="json")
        found.append(
            PublishedTool(
                tool_id=row.id,
                robot_id=row.robot_id,
                tool_name=row.name,
                robot_name=row.robot,
                archived=row.archived_at is not None,
                document=body,
            )
        )
    return found


def document(session: Session, tool_id: str) -> JsonObject | None:
    """What GET /v1/tools/{tool_id}/tcp serves now, with its ETag as `etag`; None when it
    serves no TCP (archived, no active version)."""
    try:
        served, etag = served_tcp(session, tool_id=tool_id, fmt=None, if_none_match=None)
    except (Archived, NoActiveVersion, NotFound):
        return None
    assert served is not None  # no If-None-Match given
    body: JsonObject = json.loads(served.model_dump_json())
    body["etag"] = etag
    return body


def live_tool_pages(engine: Engine, *, page: int) -> Iterator[list[str]]:
    """The ids of every live tool, `page` at a time (for a sink's full state)."""
    after: tuple[datetime, str] | None = None
    while True:
        with Session(engine) as session:
            stmt = select(Tool.id, Tool.created_at).where(Tool.archived_at.is_(None))
            if after is not None:
                stmt = stmt.where(
                    or_(
                        Tool.created_at > after[0],
                        (Tool.created_at == after[0]) & (Tool.id > after[1]),
                    )
                )
            rows = session.execute(stmt.order_by(Tool.created_at, Tool.id).limit(page)).all()
        if not rows:
            return
        yield [r.id for r in rows]
        after = (rows[-1].created_at, rows[-1].id)


def mark_delivered(session: Session, ids: Sequence[int]) -> None:
    """Record that every sink accepted these rows."""
    session.execute(
        update(OutboxMessage).where(OutboxMessage.id.in_(ids)).values(delivered_at=utcnow())
    )


def prune(session: Session, *, keep_seconds: float) -> int:
    """Delete rows delivered more than `keep_seconds` ago; how many."""
    cutoff = utcnow() - timedelta(seconds=keep_seconds)
    result = session.execute(
        delete(OutboxMessage).where(
            OutboxMessage.delivered_at.is_not(None), OutboxMessage.delivered_at <= cutoff
        )
    )
    return int(getattr(result, "rowcount", 0) or 0)
