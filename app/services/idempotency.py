"""Idempotency keys: the first response to a keyed submission, replayed for 24 h."""

from __future__ import annotations

import hashlib
import json
from datetime import UTC, datetime, timedelta

from sqlalchemy import delete, insert, select, update
from sqlalchemy.orm import Session

from app.config import get_settings
from app.errors import IdempotencyConflict
from app.jsontypes import JsonObject
from app.security.auth import Principal
from app.storage.models import IdempotencyRecord, table_of, utcnow


def request_fingerprint(tool_id: str, raw_body: JsonObject) -> str:
    """Hash of what a retry must repeat exactly: the target and the body."""
    canonical = json.dumps([tool_id, raw_body], sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def replay(
    session: Session,
    *,
    actor: Principal,
    key: str,
    fingerprint: str,
    purge: bool = True,
) -> JsonObject | None:
    """The first response to (actor, key), None if there is none (or it expired); 409 when
    the key came with another request. `purge`: also delete expired records (a write: only
    inside a write transaction)."""
    ttl = timedelta(hours=get_settings().idempotency_ttl_hours)
    oldest = utcnow() - ttl
    if purge:
        session.execute(delete(IdempotencyRecord).where(IdempotencyRecord.created_at < oldest))
    record = session.scalars(
        select(IdempotencyRecord).where(
            IdempotencyRecord.api_key_id == actor.key_id, IdempotencyRecord.key == key
        )
    ).one_or_none()
    if record is None or _aware(record.created_at) < oldest:
        return None
    if record.request_hash != fingerprint:
        raise IdempotencyConflict(
            f"Idempotency-Key {key!r} was already used with a different request body or tool; "
            "use a new key for a new submission"
        )
    return record.response


def remember(
    session: Session, *, actor: Principal, key: str, fingerprint: str, response: JsonObject
) -> None:
    """Keep the answer to (actor, key) so that a retry with the same body replays it."""
    session.connection().execute(
        _INSERT,
        {
            "api_key_id": actor.key_id,
            "key": key,
            "request_hash": fingerprint,
            "status_code": 201,
            "response": response,
            "created_at": utcnow(),
        },
    )


_INSERT = insert(table_of(IdempotencyRecord))


def replace(session: Session, *, actor: Principal, key: str, response: JsonObject) -> None:
    """The kept answer to (actor, key) becomes `response`: an answer kept before the
    controller's I/O that followed it (a re-check's deployment), completed after."""
    session.execute(
        update(IdempotencyRecord)
        .where(IdempotencyRecord.api_key_id == actor.key_id, IdempotencyRecord.key == key)
        .values(response=response)
    )


def _aware(moment: datetime) -> datetime:
    return moment if moment.tzinfo is not None else moment.replace(tzinfo=UTC)


def replay_keyed(
    session: Session, *, actor: Principal, keyed: tuple[str, str] | None, purge: bool = True
) -> JsonObject | None:
    """`replay` for a request that may carry no key: keyed is (key, fingerprint) or None."""
    if keyed is None:
        return None
    key, fingerprint = keyed
    return replay(session, actor=actor, key=key, fingerprint=fingerprint, purge=purge)


def remember_keyed(
    session: Session, *, actor: Principal, keyed: tuple[str, str] | None, response: JsonObject
) -> None:
    """`remember` for a request that may carry no key: keyed is (key, fingerprint) or None."""
    if keyed is not None:
        key, fingerprint = keyed
        remember(session, actor=actor, key=key, fingerprint=fingerprint, response=response)
