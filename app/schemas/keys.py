"""API keys."""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, BaseModel, Field

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

#: /v1/keys/me is the caller's own key: no key is named so, nor id'd so (ids are UUIDs, and
#: app.api.keys's path convertor keeps `me` from the id routes).
RESERVED_KEY_NAME = "me"


def _not_reserved(name: str) -> str:
    if name.casefold() == RESERVED_KEY_NAME:
        raise ValueError(
            f"'{name}' is a reserved word (/v1/keys/{RESERVED_KEY_NAME} is the caller's own "
            "key): give the key another name"
        )
    return name


class KeyCreate(StrictModel):
    name: Annotated[Name, AfterValidator(_not_reserved)]
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
