"""Whether this server may take traffic: its database answers and is migrated to head."""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy.exc import SQLAlchemyError

from app.storage.db import get_engine
from app.storage.migrate import current_revision, head_revision


@dataclass(frozen=True)
class DatabaseState:
    """The database's migration revision and the code's head; `unreachable` names the error
    (its class) when the database did not answer."""

    head: str | None
    revision: str | None = None
    unreachable: str | None = None

    @property
    def at_head(self) -> bool:
        """Reachable and migrated to the code's head."""
        return self.unreachable is None and self.revision == self.head


def database_state() -> DatabaseState:
    """Ask the database for its migration revision."""
    head = head_revision()
    try:
        current = current_revision(get_engine())
    except SQLAlchemyError as exc:
        return DatabaseState(head, unreachable=type(exc).__name__)
    return DatabaseState(head, current)
