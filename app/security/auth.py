"""API keys: generated, hashed at rest, looked up by hash; scopes read < calibrate < admin."""

from __future__ import annotations

import hashlib
import hmac
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple, Protocol

from sqlalchemy import Engine, bindparam, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.errors import Forbidden, Unauthorized
from app.jsontypes import JsonArray
from app.scopes import SCOPES, Scope
from app.storage.db import HeldRead, session_scope
from app.storage.models import ApiKey

KEY_PREFIX = "tcpcal_"
BOOTSTRAP_NAME = "bootstrap-admin"


@dataclass(frozen=True)
class Principal:
    """Who is calling: the API key's id, name and scope, and the robot cells it is limited
    to (None: every cell)."""

    key_id: str
    name: str
    scope: Scope
    cells: tuple[str, ...] | None = None

    def allows(self, required: Scope) -> bool:
        """True when this key's scope includes `required`."""
        return SCOPES.index(self.scope) >= SCOPES.index(required)

    def sees_cell(self, cell: str | None) -> bool:
        """True when a robot in `cell` is visible to this key."""
        return self.cells is None or (cell is not None and cell in self.cells)


#: Where a session keeps the cells of the key it works for: every lookup of a robot or a
#: tool by id, and every list, reads them (app.services.visible, app.services.scope), so that
#: the scope is applied once, by the session, not by each route.
CELLS_INFO = "tcpcal.cells"


def act_for(session: Session, principal: Principal) -> None:
    """Limit what `session` finds to the robots (and their tools) `principal` may see."""
    session.info[CELLS_INFO] = principal.cells


@contextmanager
def transaction_for(
    actor: Principal, *, write: bool, engine: Engine | None = None
) -> Iterator[Session]:
    """A transaction acting for `actor`: committed on success, rolled back on any error
    (app.storage.db.session_scope), and finding only the robots of the actor's cells and
    their tools (act_for). The one way a use case opens a transaction for its caller when it
    opens its own: one that blocks on a controller between two transactions, or runs in a
    solver process. A route's own session (app.api.deps.SessionDep) is limited to the
    caller's cells by `authenticate`."""
    with session_scope(write=write, engine=engine) as session:
        act_for(session, actor)
        yield session


def cells_of(session: Session) -> tuple[str, ...] | None:
    """The cells a session is limited to (None: every cell)."""
    cells: tuple[str, ...] | None = session.info.get(CELLS_INFO)
    return cells


def hash_key(key: str) -> str:
    """SHA-256 of a key. Keys carry 256 random bits, so a slow KDF would add nothing."""
    return hashlib.sha256(key.encode("utf-8")).hexdigest()


def generate_key() -> str:
    """A new random API key."""
    return KEY_PREFIX + secrets.token_urlsafe(32)


def _bearer(header: str | None) -> str:
    if not header:
        raise Unauthorized(
            "missing Authorization header; send 'Authorization: Bearer <api-key>'",
            headers={"WWW-Authenticate": "Bearer"},
        )
    scheme, _, token = header.partition(" ")
    if scheme.lower() != "bearer" or not token.strip():
        raise Unauthorized(
            "Authorization header must be 'Bearer <api-key>'",
            headers={"WWW-Authenticate": "Bearer"},
        )
    return token.strip()


def authenticate(session: Session, header: str | None, *, required: Scope) -> Principal:
    """The caller behind an Authorization header, checked against the required scope."""
    digest = digest_of(header)
    row = session.scalars(select(ApiKey).where(ApiKey.key_hash == digest)).one_or_none()
    principal = admit(row, digest, required=required)
    act_for(session, principal)
    return principal


class KeyColumns(NamedTuple):
    """A row of KEY_READ: what admitting a caller reads of a key (a KeyRow)."""

    id: str
    name: str
    scope: Scope
    key_hash: str
    revoked_at: datetime | None
    cells: JsonArray | None


_KEY = ApiKey.__table__
#: The key lookup as one statement on the calling thread's held connection
# (app.storage.db.HeldRead):
#: for routes on the event loop that need no session before their work (POST /v1/solve).
KEY_READ = HeldRead(
    KeyColumns,
    select(
        _KEY.c.id, _KEY.c.name, _KEY.c.scope, _KEY.c.key_hash, _KEY.c.revoked_at, _KEY.c.cells
    ).where(_KEY.c.key_hash == bindparam("digest")),
)


def authenticate_held(engine: Engine, header: str | None, *, required: Scope) -> Principal:
    """`authenticate` without a session: the key read on the thread's held connection."""
    digest = digest_of(header)
    return admit(KEY_READ.one_or_none(engine, digest=digest), digest, required=required)


def digest_of(header: str | None) -> str:
    """The hash to look a key up by, from an Authorization header (401 when malformed)."""
    return hash_key(_bearer(header))


class KeyRow(Protocol):
    """What admitting a caller reads of a key: a models.ApiKey, or the hot read's columns."""

    @property
    def id(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def scope(self) -> Scope: ...
    @property
    def key_hash(self) -> str: ...
    @property
    def revoked_at(self) -> datetime | None: ...
    @property
    def cells(self) -> JsonArray | None: ...


def admit(row: KeyRow | None, digest: str, *, required: Scope) -> Principal:
    """The caller a looked-up key row stands for: 401 unknown or revoked, 403 scope too small."""
    if row is None or row.revoked_at is not None or not hmac.compare_digest(row.key_hash, digest):
        raise Unauthorized(
            "unknown or revoked API key",
            headers={"WWW-Authenticate": 'Bearer error="invalid_token"'},
        )
    cells = None if row.cells is None else tuple(str(c) for c in row.cells)
    principal = Principal(key_id=row.id, name=row.name, scope=row.scope, cells=cells)
    if not principal.allows(required):
        raise Forbidden(f"this key has scope '{row.scope}'; this operation needs '{required}'")
    return principal


def ensure_bootstrap_key(session: Session, key: str) -> None:
    """Make `key` exist with admin scope (idempotent; safe when several workers start)."""
    digest = hash_key(key)
    if session.scalars(select(ApiKey.id).where(ApiKey.key_hash == digest)).first():
        return
    session.add(
        ApiKey(
            name=BOOTSTRAP_NAME,
            scope="admin",
            key_hash=digest,
            prefix=key[:12],
            created_by="TCPCAL_BOOTSTRAP_ADMIN_KEY",
        )
    )
    try:
        session.commit()
    except IntegrityError:
        session.rollback()  # another worker inserted it first


def authenticate_key(session: Session, key: str, *, required: Scope) -> Principal:
    """The caller behind a bare API key (no Authorization header: an OPC UA password, say),
    checked against the required scope: 401 unknown or revoked, 403 scope too small."""
    digest = hash_key(key)
    row = session.scalars(select(ApiKey).where(ApiKey.key_hash == digest)).one_or_none()
    return admit(row, digest, required=required)
