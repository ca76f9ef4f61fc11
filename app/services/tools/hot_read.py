"""The tool's hot read (app.services.lifecycle.hot_read, with the tool's declaration): the
caller's key, a tool and its active version in one statement, for GET /v1/tools/{id}/tcp as
JSON (app.services.tools.versions) or as its controller's file
(app.services.tools.controller_files)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from sqlalchemy import Engine

from app.jsontypes import JsonObject
from app.security.auth import Principal
from app.services.lifecycle import hot_read
from app.services.lifecycle.hot_read import HotRow, HotVersion
from app.services.tools.subject import TOOL

#: The tool's one statement (its binds: `digest`, `subject_id`).
HOT_READ: Final = hot_read.hot_read(TOOL)


# Plain records, not ORM objects: an instrumented __init__ cost 50 us a request here.
@dataclass(frozen=True, slots=True)
class HotTool:
    """The tool of a hot read (an app.services.tools.controller_text.ServedTool)."""

    id: str
    robot_id: str
    name: str
    slot: int | None
    load: JsonObject | None
    controller_symbol: str | None


def read_for_key(
    engine: Engine, authorization: str | None, tool_id: str
) -> tuple[Principal, HotRow]:
    """(who, the row) for the caller behind `authorization` and a tool: 401 for no key or
    an unknown or revoked one, 403 for too small a scope (a key comes before the tool)."""
    return hot_read.read_for_key(engine, TOOL, authorization, tool_id)


def active_of(found: HotRow, principal: Principal, tool_id: str) -> tuple[HotTool, HotVersion]:
    """The tool and its active version of a hot read's row, or the 404 that says why not:
    unknown (or of a robot outside the key's cells), archived, or no active version."""
    version = hot_read.active_version_of(TOOL, found, principal, tool_id)
    # Columns of the tool's row, which exists, are never NULL.
    assert found.subject_id is not None
    assert found.robot_id is not None
    assert found.subject_name is not None
    tool = HotTool(
        found.subject_id,
        found.robot_id,
        found.subject_name,
        found.slot,
        found.detail,
        found.controller_symbol,
    )
    return tool, version
