"""Query parameters shared by list endpoints."""

from __future__ import annotations

from typing import Annotated

from fastapi import Path, Query

from app.helpers.pagination import CURSOR_PATTERN, DEFAULT_LIMIT, MAX_LIMIT
from app.schemas.common import ID_PATTERN

Limit = Annotated[int, Query(ge=1, le=MAX_LIMIT, description="page size (max 500)")]
Cursor = Annotated[
    str | None, Query(pattern=CURSOR_PATTERN, description="next_cursor of the last page")
]
DEFAULT_PAGE = DEFAULT_LIMIT
#: Path ids: anything but an id this service could have issued is refused (422) before a
#: database sees it.
PathId = Annotated[str, Path(pattern=ID_PATTERN, description="resource id")]
#: Version numbers start at 1 and fit every database's 32-bit integer.
VersionNumber = Annotated[int, Path(ge=1, le=2**31 - 1, description="version number")]
