"""API key administration."""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import Conflict, Forbidden, NotFound
from app.helpers.pagination import paginate
from app.jsontypes import JsonObject
from app.scopes import Scope
from app.security.auth import Principal, generate_key, hash_key
from app.services.audit import writes as audit
from app.storage.models import ApiKey, new_id, utcnow


def create_key(
    session: Session,
    *,
    name: str,
    scope: Scope,
    actor: Principal | None,
    cells: Sequence[str] | None = None,
) -> tuple[ApiKey, str]:
    """A new key (limited to `cells` when given); the secret is returned once and only its
    hash is stored. A key limited to cells makes keys limited to some of its cells only."""
    if actor is not None:
        _within_actor_cells(actor, cells)
    key = generate_key()
    row = ApiKey(
        id=new_id(),
        name=name,
        scope=scope,
        key_hash=hash_key(key),
        prefix=key[:12],
        created_by=actor.name if actor else "cli",
        cells=None if cells is None else list(cells),
    )
    if actor is None:  # the test fixtures' and a bootstrap's keys: nobody to record
        session.add(row)
        session.flush()
        return row, key
    # The event names the key by id and name: never the secret, its hash or its prefix.
    details: JsonObject = {"name": name, "scope": scope, "cells": row.cells}
    audit.add_created(
        session, row, actor=actor, action="key.create", resource_type="api_key", details=details
    )
    return row, key


def _within_actor_cells(actor: Principal, cells: Sequence[str] | None) -> None:
    """403 naming body.cells when a key limited to cells asks for a key that sees more."""
    if actor.cells is None or (cells is not None and set(cells) <= set(actor.cells)):
        return
    raise Forbidden(
        f"this key is limited to the cells {', '.join(actor.cells)}: the keys it makes must "
        "be limited to some of them (give cells)",
        loc=("body", "cells"),
        msg="outside this key's cells",
    )


def _visible_key(actor: Principal, row: ApiKey | None) -> bool:
    """A key limited to cells sees the keys limited to some of its cells, and no other."""
    if row is None or actor.cells is None:
        return row is not None
    return row.cells is not None and set(row.cells) <= set(actor.cells)


def list_keys(
    session: Session, *, limit: int, cursor: str | None, actor: Principal | None = None
) -> tuple[Sequence[ApiKey], str | None]:
    """Keys, revoked ones included (their secrets are never shown); for a key limited to
    cells, the keys limited to some of its cells."""
    rows, next_cursor = paginate(
        session,
        select(ApiKey),
        created_col=ApiKey.created_at,
        id_col=ApiKey.id,
        limit=limit,
        cursor=cursor,
    )
    if actor is not None and actor.cells is not None:
        rows = [r for r in rows if _visible_key(actor, r)]
    return rows, next_cursor


def revoke_key(session: Session, *, key_id: str, actor: Principal) -> None:
    """Revoke a key; it answers 401 from now on."""
    row = session.get(ApiKey, key_id)
    if row is None or not _visible_key(actor, row):
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
        details={"name": row.name, "scope": row.scope, "cells": row.cells},
    )


def rotate_key(session: Session, *, key_id: str, actor: Principal) -> tuple[ApiKey, str]:
    """Replace a key by a new one of the same name and scope, in one transaction: the old
    key answers 401 from the commit on, the new secret is returned once."""
    old = session.get(ApiKey, key_id)
    if old is None:
        raise NotFound(f"no API key with id {key_id}")
    revoke_key(session, key_id=key_id, actor=actor)
    return create_key(session, name=old.name, scope=old.scope, actor=actor, cells=old.cells)
