"""API key administration."""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.auth import Principal, generate_key, hash_key
from app.errors import Conflict, NotFound
from app.helpers.pagination import paginate
from app.models import ApiKey, utcnow
from app.services import audit


def create_key(
    session: Session, *, name: str, scope: str, actor: Principal | None
) -> tuple[ApiKey, str]:
    """A new key; the secret is returned once and only its hash is stored."""
    key = generate_key()
    row = ApiKey(
        name=name,
        scope=scope,
        key_hash=hash_key(key),
        prefix=key[:12],
        created_by=actor.name if actor else "cli",
    )
    session.add(row)
    session.flush()
    if actor is not None:
        audit.record(
            session,
            actor=actor,
            action="key.create",
            resource_type="api_key",
            resource_id=row.id,
            details={"name": name, "scope": scope},
        )
    return row, key


def list_keys(
    session: Session, *, limit: int, cursor: str | None
) -> tuple[Sequence[ApiKey], str | None]:
    """Keys, revoked ones included (their secrets are never shown)."""
    return paginate(
        session,
        select(ApiKey),
        created_col=ApiKey.created_at,
        id_col=ApiKey.id,
        limit=limit,
        cursor=cursor,
    )


def revoke_key(session: Session, *, key_id: str, actor: Principal) -> None:
    """Revoke a key; it answers 401 from now on."""
    row = session.get(ApiKey, key_id)
    if row is None:
        raise NotFound(f"no API key with id {key_id}")
    if row.revoked_at is not None:
        raise Conflict(f"API key {key_id} is already revoked")
    if row.id == actor.key_id:
        raise Conflict("a key cannot revoke itself; revoke it with another admin key")
    row.revoked_at = utcnow()
    audit.record(
        session,
        actor=actor,
        action="key.revoke",
        resource_type="api_key",
        resource_id=row.id,
        details={"name": row.name},
    )


def rotate_key(session: Session, *, key_id: str, actor: Principal) -> tuple[ApiKey, str]:
    """Replace a key by a new one of the same name and scope, in one transaction: the old
    key answers 401 from the commit on, the new secret is returned once."""
    old = session.get(ApiKey, key_id)
    if old is None:
        raise NotFound(f"no API key with id {key_id}")
    revoke_key(session, key_id=key_id, actor=actor)
    return create_key(session, name=old.name, scope=old.scope, actor=actor)
