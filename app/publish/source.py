"""The publisher's side of the database: undelivered outbox rows, the current state of the
calibrated subjects they concern (each subject of app.services.subjects), marking rows
delivered and pruning them.

A subject's state is the document its read route serves (a tool's GET /v1/tools/{id}/tcp,
built by the same service: `app.services.tools.versions.served_tcp`), with the active
version's `status` (accepted or out_of_tolerance) and `activation` (how it went live: kind,
reason, at, by: app.services.lifecycle.published) added, read when it is published, never a
snapshot taken when the change was made: whatever the order in which redelivered rows
arrive, the last state a sink receives of a subject is its current one.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Sequence
from datetime import datetime, timedelta

from sqlalchemy import Engine, delete, or_, select, update
from sqlalchemy.orm import Session

from app.errors import Archived, NoActiveVersion, NotFound
from app.jsontypes import JsonObject
from app.publish.sink import Message, PublishedSubject
from app.services.lifecycle.published import active_statuses, last_activations
from app.services.subjects import SERVED, Served
from app.storage.models import SUBJECT_KEYS, OutboxMessage, Robot, utcnow


def undelivered(session: Session, *, limit: int) -> list[Message]:
    """The oldest undelivered rows, in id order (commit order per tool)."""
    rows = session.scalars(
        select(OutboxMessage)
        .where(OutboxMessage.delivered_at.is_(None))
        .order_by(OutboxMessage.id)
        .limit(limit)
    )
    return [
        Message(
            r.id, r.action, r.robot_id, {key: getattr(r, key) for key in SUBJECT_KEYS}, r.payload
        )
        for r in rows
    ]


#: A subject of a batch, and its id.
Concerned = tuple[Served, str]


def subjects_concerned(session: Session, messages: Sequence[Message]) -> list[Concerned]:
    """The subjects whose state follows the messages: each message's subject (by the outbox
    column of its key, app.storage.models.SUBJECT_KEYS), and for a message about a robot
    alone (an update, an archive) the robot's live subjects and those archived with it. In
    order of first mention, subject by subject."""
    robots = [m.robot_id for m in messages if m.robot_id is not None and not _named(m)]
    found: list[Concerned] = []
    for served in SERVED:
        subject = served.subject
        ordered = {key: None for m in messages if isinstance(key := m.ids.get(subject.key), str)}
        if robots:
            table = subject.table
            stmt = (
                select(table.c.id)
                .join(Robot, Robot.id == table.c.robot_id)
                .where(
                    table.c.robot_id.in_(robots),
                    or_(table.c.archived_at.is_(None), table.c.archived_at == Robot.archived_at),
                )
                .order_by(table.c.created_at, table.c.id)
            )
            ordered.update(dict.fromkeys(session.scalars(stmt)))
        found.extend((served, subject_id) for subject_id in ordered)
    return found


def _named(message: Message) -> bool:
    """Whether a message names a subject (not a robot alone)."""
    return any(value is not None for value in message.ids.values())


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


def states(session: Session, concerned: Iterable[Concerned]) -> list[PublishedSubject]:
    """The current state of each subject (unknown ids are left out), subject by subject."""
    wanted: dict[Served, list[str]] = {}
    for served, subject_id in concerned:
        wanted.setdefault(served, []).append(subject_id)
    return [state for served, ids in wanted.items() for state in _states_of(session, served, ids)]


def _states_of(session: Session, served: Served, ids: list[str]) -> list[PublishedSubject]:
    subject = served.subject
    table = subject.table
    names = {
        row.id: row
        for row in session.execute(
            select(
                table.c.id,
                table.c.robot_id,
                table.c.name,
                table.c.archived_at,
                Robot.name.label("robot"),
            )
            .join(Robot, Robot.id == table.c.robot_id)
            .where(table.c.id.in_(ids))
        )
    }
    statuses = active_statuses(session, subject, ids)
    activations = last_activations(session, subject, ids)
    found = []
    for subject_id in ids:
        row = names.get(subject_id)
        if row is None:
            continue
        body = document(session, served, subject_id)
        if body is not None:
            activation = activations.get(subject_id)
            body["status"] = statuses.get(subject_id)
            body["activation"] = None if activation is None else activation.model_dump(mode="json")
        found.append(
            PublishedSubject(
                subject=subject,
                subject_id=row.id,
                robot_id=row.robot_id,
                name=row.name,
                robot_name=row.robot,
                archived=row.archived_at is not None,
                document=body,
            )
        )
    return found


def document(session: Session, served: Served, subject_id: str) -> JsonObject | None:
    """What the subject's read route (a tool's GET /v1/tools/{tool_id}/tcp) serves now, with
    its ETag as `etag`; None when it serves nothing (archived, no active version)."""
    try:
        answer, etag = served.document(session, subject_id)
    except (Archived, NoActiveVersion, NotFound):
        return None
    assert answer is not None  # no If-None-Match given
    body: JsonObject = json.loads(answer.model_dump_json())
    body["etag"] = etag
    return body


def live_pages(engine: Engine, *, page: int) -> Iterator[list[Concerned]]:
    """Every live subject, `page` at a time (for a sink's full state), subject by subject."""
    for served in SERVED:
        table = served.subject.table
        after: tuple[datetime, str] | None = None
        while True:
            with Session(engine) as session:
                stmt = select(table.c.id, table.c.created_at).where(table.c.archived_at.is_(None))
                if after is not None:
                    stmt = stmt.where(
                        or_(
                            table.c.created_at > after[0],
                            (table.c.created_at == after[0]) & (table.c.id > after[1]),
                        )
                    )
                order = (table.c.created_at, table.c.id)
                rows = session.execute(stmt.order_by(*order).limit(page)).all()
            if not rows:
                break
            yield [(served, r.id) for r in rows]
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
