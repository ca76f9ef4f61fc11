"""The scopes of an API key, each including the ones before it: read < calibrate < admin.

Pure Python, so that the request schemas (app.schemas.keys), the key check (app.security.auth) and
the CLI read the one list without importing each other.
"""

from __future__ import annotations

from typing import Literal, get_args

Scope = Literal["read", "calibrate", "admin"]

#: Every scope, narrowest first: a key's scope allows what any scope before it allows.
SCOPES: tuple[Scope, ...] = get_args(Scope)
