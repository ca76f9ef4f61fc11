"""Lookups of rows that can be archived (robots, tools): live, or a 404 that says why not."""

from __future__ import annotations

from datetime import datetime
from typing import Protocol, TypeVar

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import Archived, NotFound
from app.models import Robot, Tool

Live = TypeVar("Live", Robot, Tool)


def get_live(session: Session, model: type[Live], row_id: str, *, for_update: bool) -> Live:
    """A row that is not archived, or 404 (/not-found, or /archived when it was deleted)."""
    what = model.__name__.lower()
    stmt = select(model).where(model.id == row_id)
    if for_update:
        stmt = stmt.with_for_update()
    return live_or_404(session.scalars(stmt).one_or_none(), what, row_id)


class _Archivable(Protocol):
    @property
    def name(self) -> str: ...
    @property
    def archived_at(self) -> datetime | None: ...


Row = TypeVar("Row", bound=_Archivable)


def live_or_404(row: Row | None, what: str, row_id: str) -> Row:
    """The row when it exists and is not archived; else the 404 that says which."""
    if row is None:
        raise NotFound(f"no {what} with id {row_id}")
    if row.archived_at is not None:
        raise Archived(f"{what} {row_id} ({row.name}) was archived")
    return row
