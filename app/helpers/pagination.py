"""Keyset pagination over (created_at, id): stable under inserts, opaque cursors."""

from __future__ import annotations

import base64
import json
from collections.abc import Sequence
from datetime import datetime
from typing import TypeVar

from sqlalchemy import Select, and_, or_
from sqlalchemy.orm import InstrumentedAttribute, Session

from app.errors import InvalidInput

DEFAULT_LIMIT = 50
MAX_LIMIT = 500

M = TypeVar("M")


def encode_cursor(created_at: datetime, row_id: str) -> str:
    """Opaque cursor pointing after the given row."""
    raw = json.dumps([created_at.isoformat(), row_id]).encode()
    return base64.urlsafe_b64encode(raw).decode().rstrip("=")


def decode_cursor(cursor: str) -> tuple[datetime, str]:
    """Inverse of encode_cursor; 422 naming `cursor` when it is not one of ours."""
    try:
        padded = cursor + "=" * (-len(cursor) % 4)
        created, row_id = json.loads(base64.urlsafe_b64decode(padded.encode()))
        after = datetime.fromisoformat(created)
        if after.tzinfo is None:
            raise ValueError("cursor timestamp without a time zone")
        return after, str(row_id)
    except (ValueError, TypeError, json.JSONDecodeError) as exc:
        raise InvalidInput(
            "invalid-cursor",
            "cursor is not a value returned as next_cursor",
            loc=("query", "cursor"),
        ) from exc


def paginate(
    session: Session,
    stmt: Select[M],
    *,
    created_col: InstrumentedAttribute[datetime],
    id_col: InstrumentedAttribute[str],
    limit: int,
    cursor: str | None,
) -> tuple[Sequence[M], str | None]:
    """One page of `stmt` ordered by (created_at, id) and the cursor of the next page."""
    if cursor:
        after_created, after_id = decode_cursor(cursor)
        stmt = stmt.where(
            or_(
                created_col > after_created,
                and_(created_col == after_created, id_col > after_id),
            )
        )
    rows: list[M] = list(session.scalars(stmt.order_by(created_col, id_col).limit(limit + 1)))
    next_cursor = None
    if len(rows) > limit:
        rows = rows[:limit]
        last = rows[-1]
        next_cursor = encode_cursor(getattr(last, "created_at"), getattr(last, "id"))  # noqa: B009
    return rows, next_cursor
