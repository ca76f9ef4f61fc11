"""GET /v1/tools/{tool_id}/tcp's use case, the read cell controllers poll: the caller's key,
the tool and its active version in one statement (app.services.tools.hot_read) on the event loop's
held connection (app.storage.db.loop_engine), served as JSON or as the controller's own file."""

from __future__ import annotations

from typing import NamedTuple

from app.schemas.tools import ActiveTcp
from app.security.auth import Principal
from app.services.tools import controller_files, versions
from app.storage.db import loop_engine
from app.vendors.files import ControllerFile
from app.words import ControllerFormat


class ServedTcp(NamedTuple):
    """Who asked, the answer's ETag and the answer: the JSON document or the controller's
    file, neither when the client's copy is current (If-None-Match: 304)."""

    key: Principal
    etag: str
    document: ActiveTcp | None = None
    file: ControllerFile | None = None


def active_tcp(
    tool_id: str,
    /,
    *,
    authorization: str | None,
    fmt: ControllerFormat | None,
    if_none_match: str | None,
    file_base_url: str | None,
) -> ServedTcp:
    """The active TCP for the caller behind `authorization`: as JSON, or as the controller's
    file when `file_base_url` (the server's base URL, which the file's header names) is given."""
    if file_base_url is not None:
        key, served, etag = controller_files.served_file_for_key(
            loop_engine(),
            authorization=authorization,
            tool_id=tool_id,
            fmt=fmt,
            if_none_match=if_none_match,
            base_url=file_base_url,
        )
        return ServedTcp(key, etag, file=served)
    # No ORM and no thread hop: tens of microseconds on SQLite, one round trip on PostgreSQL.
    key, document, etag = versions.served_tcp_for_key(
        loop_engine(),
        authorization=authorization,
        tool_id=tool_id,
        fmt=fmt,
        if_none_match=if_none_match,
    )
    return ServedTcp(key, etag, document=document)
