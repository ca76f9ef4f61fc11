"""Keyset pagination over (created_at, id): stable under inserts, opaque cursors."""

from __future__ import annotations

import hashlib
import re
import uuid
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime, timedelta
from typing import TypeVar, TypeVarTuple

from sqlalchemy import Column, Row, Select, literal, tuple_
from sqlalchemy.orm import InstrumentedAttribute, Session

from app.errors import InvalidInput

DEFAULT_LIMIT = 50
MAX_LIMIT = 500

M = TypeVar("M")
R = TypeVar("R")
Ts = TypeVarTuple("Ts")


#: A cursor: the position after a row, as 16 hex digits of its creation time (microseconds
#: since 1970, UTC) and the 32 hex digits of its id (a UUID). Every string of this shape is a
#: position; one past every row gives an empty page.
CURSOR_PATTERN = r"^[0-9a-f]{48}$"
_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)
_LAST = datetime.max.replace(tzinfo=UTC)
_MAX_ID = 2**63 - 1


def encode_cursor(created_at: datetime, row_id: str) -> str:
    """Opaque cursor pointing after the given row."""
    if created_at.tzinfo is None:
        created_at = created_at.replace(tzinfo=UTC)
    micros = (created_at - _EPOCH) // timedelta(microseconds=1)
    return f"{micros:016x}{uuid.UUID(row_id).hex}"


def decode_cursor(cursor: str) -> tuple[datetime, str]:
    """Inverse of encode_cursor; 422 naming `cursor` when it is not of the cursor's shape."""
    if re.fullmatch(CURSOR_PATTERN, cursor) is None:
        raise InvalidInput(
            "invalid-cursor",
            "cursor is not a value returned as next_cursor (48 hex digits)",
            loc=("query", "cursor"),
        )
    micros = int(cursor[:16], 16)
    try:
        after = _EPOCH + timedelta(microseconds=micros)
    except OverflowError:
        after = _LAST
    return after, str(uuid.UUID(cursor[16:]))


def _after(
    stmt: Select[*Ts],
    created_col: InstrumentedAttribute[datetime] | Column[datetime],
    id_col: InstrumentedAttribute[str] | Column[str],
    cursor: str | None,
    *,
    newest_first: bool = False,
) -> Select[*Ts]:
    """`stmt` from the row after the cursor on, in (created_at, id) order (newest first:
    descending, "after" then meaning older)."""
    if cursor:
        after_created, after_id = decode_cursor(cursor)
        # A row value: both SQLite and PostgreSQL seek to it in a (created_at, id) index,
        # where the equivalent OR of two conditions scanned every row before it.
        key = tuple_(created_col, id_col)
        at = tuple_(literal(after_created, created_col.type), literal(after_id, id_col.type))
        stmt = stmt.where(key < at if newest_first else key > at)
    if newest_first:
        return stmt.order_by(created_col.desc(), id_col.desc())
    return stmt.order_by(created_col, id_col)


def _cut(rows: list[R], limit: int) -> tuple[list[R], str | None]:
    """The first `limit` of limit + 1 rows and the cursor after them (None: no more)."""
    if len(rows) <= limit:
        return rows, None
    last = rows[limit - 1]
    return rows[:limit], encode_cursor(getattr(last, "created_at"), getattr(last, "id"))  # noqa: B009


def paginate(
    session: Session,
    stmt: Select[M],
    *,
    created_col: InstrumentedAttribute[datetime],
    id_col: InstrumentedAttribute[str],
    limit: int,
    cursor: str | None,
    newest_first: bool = False,
) -> tuple[Sequence[M], str | None]:
    """One page of `stmt` (one entity) ordered by (created_at, id), or newest first, and
    the next cursor."""
    stmt = _after(stmt, created_col, id_col, cursor, newest_first=newest_first)
    stmt = stmt.limit(limit + 1)
    return _cut(list(session.scalars(stmt)), limit)


def paginate_rows(
    session: Session,
    stmt: Select[*Ts],
    *,
    created_col: InstrumentedAttribute[datetime] | Column[datetime],
    id_col: InstrumentedAttribute[str] | Column[str],
    limit: int,
    cursor: str | None,
    params: Mapping[str, object] | None = None,
) -> tuple[list[Row[*Ts]], str | None]:
    """`paginate` for a select of columns (rows with `created_at` and `id` among them): no
    ORM objects, for pages that show a few columns of many rows. `params`: the values of
    the statement's bound parameters."""
    stmt = _after(stmt, created_col, id_col, cursor).limit(limit + 1)
    return _cut(list(session.execute(stmt, params)), limit)


def paginate_newest_first(
    session: Session,
    stmt: Select[M],
    *,
    id_col: InstrumentedAttribute[int],
    limit: int,
    cursor: str | None,
    query: str | None = None,
) -> tuple[Sequence[M], str | None]:
    """One page of `stmt` newest first, keyed on an increasing integer id (audit rows); the
    cursor has the same 48-hex shape as the others, the id in its last 32 digits. `query`:
    the filters that made `stmt`, as a string; the cursor then carries their fingerprint in
    its first 16 digits, and a cursor made by another query is refused (422), since it
    would skip or repeat rows of this one."""
    tag = 0 if query is None else int(hashlib.sha256(query.encode()).hexdigest()[:16], 16)
    if cursor:
        decode_cursor(cursor)  # the shape check and its 422
        if query is not None and int(cursor[:16], 16) != tag:
            raise InvalidInput(
                "invalid-cursor",
                "cursor was made by another query (other filters): send it with the same "
                "filters as the page it came from, or start again without cursor",
                loc=("query", "cursor"),
            )
        # ids beyond the database's 64-bit integers all mean "after every row"
        stmt = stmt.where(id_col < min(int(cursor[16:], 16), _MAX_ID))
    rows: list[M] = list(session.scalars(stmt.order_by(id_col.desc()).limit(limit + 1)))
    next_cursor = None
    if len(rows) > limit:
        rows = rows[:limit]
        next_cursor = f"{tag:016x}{int(getattr(rows[-1], 'id')):032x}"  # noqa: B009
    return rows, next_cursor
