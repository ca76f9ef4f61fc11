"""API keys."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, Field

from app.schemas.common import Name, StrictModel, Timestamp
from app.scopes import Scope

#: The robot cells a key is limited to: names as robots carry them in `cell`.
Cells = Annotated[
    list[Annotated[Name, Field(strict=True)]],
    Field(
        min_length=1,
        max_length=100,
        description="the robot cells this key is limited to (robots whose `cell` is one of "
        "these, and their tools); leave it out for a key of every cell",
        examples=[["cell-12"]],
    ),
]


class KeyCreate(StrictModel):
    name: Name
    scope: Scope
    cells: Cells | None = None


class KeyOut(BaseModel):
    id: str
    name: str
    scope: Scope
    prefix: str
    cells: list[str] | None = None
    created_at: Timestamp
    created_by: str | None
    revoked_at: Timestamp | None


class KeyCreated(KeyOut):
    key: str


class KeyMe(BaseModel):
    """The key a request was made with, as a client needs to know it (never the key)."""

    id: str
    name: str
    scope: Scope
