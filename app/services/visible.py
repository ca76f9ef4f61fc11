"""Lookups of rows that can be archived (robots, tools): live, or a 404 that says why not;
and the one place a key's cells limit what it finds.

A key limited to cells (app.security.auth.Principal.cells, kept by the session:
app.security.auth.act_for) finds only the robots of those cells and their tools: any other is looked
up with the cells in the statement and so is exactly as absent as an id nobody issued (the same 404,
never a 403 that would confirm it exists).
"""

from __future__ import annotations

from datetime import datetime
from typing import Protocol, TypeVar

from sqlalchemy import Column, ColumnElement, Select, select
from sqlalchemy.orm import InstrumentedAttribute, Session

from app.errors import Archived, NotFound
from app.security.auth import cells_of
from app.storage.models import Robot, Tool

Live = TypeVar("Live", Robot, Tool)
S = TypeVar("S", bound=Select)  # type: ignore[type-arg]


def get_live(session: Session, model: type[Live], row_id: str, *, for_update: bool) -> Live:
    """A row that is not archived, or 404 (/not-found, or /archived when it was deleted)."""
    what = model.__name__.lower()
    stmt = select(model).where(model.id == row_id)
    robot_col = Robot.id if model is Robot else Tool.robot_id
    stmt = in_scope(session, stmt, robot_col)
    if for_update:
        stmt = stmt.with_for_update()
    return live_or_404(session.scalars(stmt).one_or_none(), what, row_id)


def robots_of(cells: tuple[str, ...]) -> ColumnElement[bool]:
    """The condition "the robot id in Robot.id is of one of `cells`"."""
    return Robot.cell.in_(cells)


def in_scope(
    session: Session,
    stmt: S,
    robot_id: InstrumentedAttribute[str] | InstrumentedAttribute[str | None] | Column[str],
) -> S:
    """`stmt` limited to the rows whose `robot_id` column names a robot the session's key may
    see (unchanged for a key of every cell)."""
    cells = cells_of(session)
    if cells is None:
        return stmt
    if robot_id is Robot.id:
        return stmt.where(robots_of(cells))
    return stmt.where(robot_id.in_(select(Robot.id).where(robots_of(cells))))


def robot_visible(session: Session, robot_id: str | None) -> bool:
    """True when the session's key may see the robot (always, for a key of every cell)."""
    cells = cells_of(session)
    if cells is None:
        return True
    robot = None if robot_id is None else session.get(Robot, robot_id)
    return robot is not None and robot.cell in cells


def visible_tool(session: Session, tool_id: str) -> Tool | None:
    """The tool with this id when it exists and the session's key may see its robot."""
    tool = session.get(Tool, tool_id)
    return tool if tool is not None and robot_visible(session, tool.robot_id) else None


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
