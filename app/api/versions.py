"""HTTP for versions, activation and the served TCP (JSON or controller text)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Header, Query, Request, Response
from fastapi.responses import PlainTextResponse

from app.api.params import PathId, VersionNumber
from app.api.tools import IfMatch
from app.db import loop_engine
from app.deps import CalibrateKey, ReadKey, SessionDep
from app.exports import file_name
from app.helpers.etags import IF_NONE_MATCH_PATTERN
from app.middleware import KEY_NAME
from app.schemas.common import ControllerFormat
from app.schemas.tools import ActiveTcp, Tool, ToolTable, Version, VersionList
from app.services import tools, versions

router = APIRouter(tags=["versions"])

FormatQuery = Annotated[ControllerFormat | None, Query(description="controller text format")]


@router.get("/v1/tools/{tool_id}/versions", response_model=VersionList)
def list_versions(tool_id: PathId, session: SessionDep, key: ReadKey) -> object:
    """Every version of a tool's TCP with who made it and why, and the history of activations."""
    tool, rows, history = versions.list_versions(session, tool_id=tool_id)
    return {
        "items": [versions.version_document(r, tool) for r in rows],
        "activations": history,
    }


@router.get("/v1/tools/{tool_id}/versions/{version}", response_model=Version)
def get_version(
    tool_id: PathId, version: VersionNumber, session: SessionDep, key: ReadKey
) -> object:
    """One version of a tool's TCP."""
    row = versions.get_version(session, tool_id=tool_id, version=version)
    return versions.version_document(row, tools.get_tool(session, tool_id))


@router.post("/v1/tools/{tool_id}/versions/{version}/activate", response_model=Tool)
def activate_version(
    tool_id: PathId,
    version: VersionNumber,
    response: Response,
    session: SessionDep,
    key: CalibrateKey,
    if_match: IfMatch = None,
) -> object:
    """Make a version the active TCP (roll back by activating an older one); honours If-Match
    with the tool's ETag, 412 when stale."""
    tool = versions.activate_version(
        session, tool_id=tool_id, version=version, if_match=if_match, actor=key
    )
    response.headers["ETag"] = tools.tool_etag(tool)
    return tool


@router.get(
    "/v1/tools/{tool_id}/tcp",
    response_model=ActiveTcp,
    responses={
        200: {"content": {"text/plain": {"schema": {"type": "string"}}}},
        304: {"description": "not modified (If-None-Match)"},
    },
)
async def get_active_tcp(
    tool_id: PathId,
    request: Request,
    format: FormatQuery = None,
    if_none_match: Annotated[str | None, Header(pattern=IF_NONE_MATCH_PATTERN)] = None,
    accept: Annotated[str | None, Header(max_length=1000)] = None,
    authorization: Annotated[str | None, Header(include_in_schema=False)] = None,
) -> Response:
    """The active TCP a cell controller reads, with a strong ETag (If-None-Match -> 304);
    `?format=` adds the controller's own text. With `Accept: text/plain` (and `?format=`) the
    controller text alone, as a file to save and load (Content-Disposition names it)."""
    as_text = "text/plain" in (accept or "")
    # The hot path, on the event loop without a threadpool hop: the key check and the read
    # are one indexed statement (tens of microseconds on SQLite, one round trip on PostgreSQL).
    key, document, etag = versions.served_tcp_for_key(
        loop_engine(),
        authorization=authorization,
        tool_id=tool_id,
        fmt=format,
        if_none_match=if_none_match,
        as_text=as_text,
    )
    request.scope[KEY_NAME] = key.name  # for the access log line; never the key
    headers = {"ETag": etag, "Vary": "Accept"}
    if document is None:
        return Response(status_code=304, headers=headers)
    if as_text and document.controller is not None and format is not None:
        name = file_name(format, document.tool_name, document.slot)
        headers["Content-Disposition"] = f'attachment; filename="{name}"'
        return PlainTextResponse(document.controller.text, headers=headers)
    # Serialised by pydantic in one pass (no dict, no json.dumps); validated when it was built.
    return Response(document.model_dump_json(), media_type="application/json", headers=headers)


@router.get("/v1/robots/{robot_id}/tool-table", response_model=ToolTable)
def tool_table(
    robot_id: PathId, session: SessionDep, key: ReadKey, format: FormatQuery = None
) -> object:
    """Every live tool of a robot with its active TCP, in one answer; tools without one are
    listed apart."""
    return versions.tool_table(session, robot_id=robot_id, fmt=format)
