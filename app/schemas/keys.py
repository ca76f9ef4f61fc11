"""API keys."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel

from app.schemas.common import Name, StrictModel, Timestamp

Scope = Literal["read", "calibrate", "admin"]


class KeyCreate(StrictModel):
    name: Name
    scope: Scope


class KeyOut(BaseModel):
    id: str
    name: str
    scope: Scope
    prefix: str
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
