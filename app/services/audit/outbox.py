"""The transactional outbox: what the plant must hear of, written with the change itself.

Every change a consumer of the plant must see (an activation or rollback, an archive of a
tool or robot, a deployment, a controller state, a check, a calibration stored) writes an
audit event through `app.services.audit.writes.record`, and those events are inserted as the
transaction commits. `write` is called from that same place with the same rows: every audit
event that concerns a robot or a calibrated subject (has `robot_id`, or a subject's key:
`tool_id`, app.storage.models.SUBJECT_KEYS) becomes an `outbox` row
in the same transaction, so no service can change something and forget to tell the plant,
and a rolled-back change is never published. Events about API keys (no robot, no tool) stay
in the audit trail only: the plant's broker is no place for who holds which key.

Order. The publisher (`tcpcal publish`, app.publish.runner) sends rows by ascending `id`
and must send a tool's rows in the order their transactions committed. An id is allocated
when the row is inserted, which is before COMMIT, so with concurrent transactions on
PostgreSQL a later id could commit first. Two things keep ids in commit order:
- a tool's changes are serialised by its row lock (`services.versions.lock_tool`, or the
  FOR UPDATE of `get_tool(..., for_update=True)` on archive), taken before anything is
  written and held to COMMIT, so the next change of that tool allocates its ids after the
  previous one committed;
- and, for changes that do not take the tool's row lock (a check, a controller state),
  the rows are inserted as the very last statements of the transaction under a
  transaction-scoped advisory lock (`pg_advisory_xact_lock(OUTBOX_ORDER_LOCK)`), released
  by COMMIT itself: an outbox-writing transaction cannot allocate an id while another one
  holds ids it has not committed yet, so `id` order is commit order across the fleet. The
  lock is held only from the INSERT to the COMMIT (no other statement runs in between), so
  it serialises commits, not the work before them; nothing that holds it ever waits on
  another lock, so it cannot deadlock.
SQLite has one writer at a time (BEGIN IMMEDIATE and `app.storage.db.SqliteWriters`), so ids are
allocated in commit order already.

The publisher does not keep a cursor either: each pass reads every undelivered row in id
order, so a row that committed late is still sent on the next pass.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path

from sqlalchemy import Engine, func, insert, select, text
from sqlalchemy.orm import Session

try:
    import fcntl
except ImportError:  # Windows: no flock
    fcntl = None  # type: ignore[assignment]

from app.jsontypes import JsonObject
from app.logs import REQUEST_ID
from app.storage.db import DriverWrite, is_sqlite
from app.storage.models import SUBJECT_KEYS, OutboxMessage, table_of

#: The transaction-scoped advisory lock that orders outbox inserts by commit on PostgreSQL
#: (a constant of the service's own: int64 of "tcpcal.outbox.order").
OUTBOX_ORDER_LOCK = 0x7463_7063_616C_6F01
_ORDER = text("SELECT pg_advisory_xact_lock(:key)")
#: The session advisory lock one publisher per fleet holds on PostgreSQL (app.publish.lock)
#: ("tcpcal.publish" as an int64; another key than OUTBOX_ORDER_LOCK).
PUBLISHER_LOCK = 0x7463_7063_616C_7002
_PUBLISHER_HELD = text(
    "SELECT EXISTS (SELECT 1 FROM pg_locks WHERE locktype = 'advisory' AND granted"
    " AND database = (SELECT oid FROM pg_database WHERE datname = current_database())"
    " AND classid = :hi AND objid = :lo AND objsubid = 1)"
)
_INSERT = DriverWrite(insert(table_of(OutboxMessage)))


def event_of(row: Mapping[str, object]) -> JsonObject:
    """The event a consumer receives for an audit row (API.md v1.2: `{prefix}/events`; v1.3
    adds `kind` and `reason`)."""
    details = row.get("details")
    if not isinstance(details, Mapping):
        details = {}
    version = row.get("version")
    if version is None:
        version = details.get("version")
    kind, reason = kind_and_reason(details)
    at = row["at"]
    assert isinstance(at, datetime)
    request_id = row.get("request_id", REQUEST_ID.get())
    return {
        "action": str(row["action"]),
        **{key: _text_or_none(row.get(key)) for key in SUBJECT_KEYS},
        "robot_id": _text_or_none(row.get("robot_id")),
        "version": version if isinstance(version, int) else None,
        "actor": str(row["actor"]),
        "at": at.astimezone(UTC).isoformat().replace("+00:00", "Z"),  # as the API writes it
        "request_id": _text_or_none(request_id),
        "kind": kind,
        "reason": reason,
    }


def kind_and_reason(details: Mapping[str, object]) -> tuple[str | None, str | None]:
    """(kind, reason) of an audit event's details: the kind of an activation (explicit,
    forced, rollback, calibration:auto, ...), None for other changes; the words the person
    gave with the change (an activation, a rollback, a deployment), None when none were.
    (An activation's audit `reason` is the kind when no words were given:
    app.services.lifecycle.versions.activate.)"""
    kind = details.get("kind")
    reason = details.get("reason")
    kind = kind if isinstance(kind, str) else None
    reason = reason if isinstance(reason, str) and reason != kind else None
    return kind, reason


def _text_or_none(value: object) -> str | None:
    return None if value is None else str(value)


def concerns_plant(row: Mapping[str, object]) -> bool:
    """Whether an audit row is one the plant hears of: it concerns a robot or a calibrated
    subject (a tool)."""
    return any(row.get(key) is not None for key in ("robot_id", *SUBJECT_KEYS))


def write(session: Session, audit_rows: Sequence[Mapping[str, object]]) -> None:
    """Insert the outbox rows of a committing transaction's audit rows (called as the
    transaction commits, after its last other statement: see the module's note on order)."""
    now = datetime.now(UTC)  # the real time, also under app.storage.models.clock_at (the demo)
    rows = [
        {
            "created_at": now,
            "action": str(row["action"]),
            "robot_id": row.get("robot_id"),
            **{key: row.get(key) for key in SUBJECT_KEYS},
            "payload": event_of(row),
            "delivered_at": None,
        }
        for row in audit_rows
        if concerns_plant(row)
    ]
    if not rows:
        return
    session.flush()  # pending ORM changes first: nothing may wait on a row lock once ordered
    conn = session.connection()
    if not is_sqlite(conn.engine):
        conn.execute(_ORDER, {"key": OUTBOX_ORDER_LOCK})
    _INSERT.execute(session, rows)


def oldest_undelivered_age(session: Session) -> float:
    """Seconds since the oldest undelivered row was written; 0 when every row was delivered
    (the gauge tcpcal_outbox_oldest_undelivered_age_seconds: a publisher down, or a broker
    it cannot reach, makes it grow)."""
    oldest = session.scalar(
        select(func.min(OutboxMessage.created_at)).where(OutboxMessage.delivered_at.is_(None))
    )
    if oldest is None:
        return 0.0
    return max(0.0, (datetime.now(UTC) - oldest).total_seconds())


def undelivered_count(session: Session) -> int:
    """How many rows wait for the publisher."""
    return int(
        session.scalar(
            select(func.count())
            .select_from(OutboxMessage)
            .where(OutboxMessage.delivered_at.is_(None))
        )
        or 0
    )


def publisher_lock_file(database: str) -> Path:
    """The file a SQLite database's publisher holds an exclusive flock on (app.publish.lock)."""
    return Path(f"{database}-publisher.lock")


def publisher_running(engine: Engine) -> bool:
    """Whether a publisher (`tcpcal publish`) holds the fleet's publisher lock now."""
    if not is_sqlite(engine):
        with engine.connect() as conn:
            held = conn.execute(
                _PUBLISHER_HELD,
                {"hi": PUBLISHER_LOCK >> 32, "lo": PUBLISHER_LOCK & 0xFFFF_FFFF},
            ).scalar_one()
        return bool(held)
    database = engine.url.database or ""
    path = publisher_lock_file(database)
    if fcntl is None or not path.exists():
        return False
    with path.open("rb") as file:
        try:  # a shared lock is refused while the publisher holds its exclusive one
            fcntl.flock(file.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        with contextlib.suppress(OSError):
            fcntl.flock(file.fileno(), fcntl.LOCK_UN)
    return False
