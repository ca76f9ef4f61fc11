"""HTTP for a tool's versions, activation and the served TCP (JSON or controller text): the
versions' routes are every subject's (app.api.subject_routes), with the tool's documents."""

from __future__ import annotations

from typing import cast

from fastapi import APIRouter, Request, Response
from fastapi.responses import PlainTextResponse

from app.api.deps import ReadKey, SessionDep, label_request
from app.api.params import (
    ACCEPT,
    FORMAT,
    IF_NONE_MATCH,
    AcceptHeader,
    FormatQuery,
    PathId,
    RawParam,
)
from app.api.subject_routes import SubjectRoutes, version_routes
from app.schemas.common import ID_PATTERN
from app.schemas.tools import ActiveTcp, Tool, ToolTable, Version, VersionList
from app.services.tools import active_tcp, controller_files, versions
from app.services.tools.subject import TOOL
from app.words import ControllerFormat

router = APIRouter(tags=["versions"])

#: The parameters of the hot read, read by hand (see RawParam).
TOOL_ID = RawParam(
    "path",
    "tool_id",
    "Tool Id",
    "an id this service issued (1-64 of A-Za-z0-9_-); take it from GET /v1/tools",
    description="resource id",
    pattern=ID_PATTERN,
)


# First: the route cell controllers poll is matched before the others.
@router.get(
    "/v1/tools/{tool_id}/tcp",
    response_model=ActiveTcp,
    responses={
        200: {"content": {"text/plain": {"schema": {"type": "string"}}}},
        304: {"description": "not modified (If-None-Match)"},
    },
    openapi_extra={"parameters": [p.openapi() for p in (TOOL_ID, FORMAT, IF_NONE_MATCH, ACCEPT)]},
)
async def get_active_tcp(request: Request) -> Response:
    """The active TCP a cell controller reads, with a strong ETag (If-None-Match -> 304);
    `?format=` adds the controller's own text. With `Accept: text/plain` (and `?format=`) the
    file the controller loads (a RAPID module, $config.dat lines, a TP program, TOOL.CND, a
    URScript function, a TMscript line) with a header saying which version, calibrated when
    and by whom (Content-Disposition names it)."""
    tool_id = TOOL_ID.read(request)
    assert tool_id is not None  # a path parameter
    format = cast(ControllerFormat | None, FORMAT.read(request))
    if_none_match = IF_NONE_MATCH.read(request)
    as_text = "text/plain" in (ACCEPT.read(request) or "")
    # On the event loop, no dependency and no threadpool hop: the key check and the read are
    # one indexed statement (app.services.tools.hot_read).
    served = active_tcp.active_tcp(
        authorization=request.headers.get("authorization"),
        tool_id=tool_id,
        fmt=format,
        if_none_match=if_none_match,
        file_base_url=str(request.base_url) if as_text else None,
    )
    label_request(request, served.key)
    headers = {"ETag": served.etag, "Vary": "Accept"}
    if served.document is not None:
        # Serialised by pydantic in one pass (no dict, no json.dumps); validated when built.
        return Response(
            served.document.model_dump_json(), media_type="application/json", headers=headers
        )
    if served.file is not None:
        headers["Content-Disposition"] = f'attachment; filename="{served.file.name}"'
        return PlainTextResponse(served.file.text, headers=headers)
    return Response(status_code=304, headers=headers)


router.include_router(
    version_routes(
        SubjectRoutes(
            subject=TOOL,
            document=Tool,
            version=Version,
            version_list=VersionList,
            version_document=versions.version_document,
            names="",
        )
    )
)


@router.get(
    "/v1/robots/{robot_id}/tool-table",
    response_model=ToolTable,
    responses={200: {"content": {"text/plain": {"schema": {"type": "string"}}}}},
)
def tool_table(
    robot_id: PathId,
    request: Request,
    session: SessionDep,
    key: ReadKey,
    format: FormatQuery = None,
    accept: AcceptHeader = None,
) -> ToolTable | PlainTextResponse:
    """Every live tool of a robot with its active TCP, in one answer; tools without one are
    listed apart. With `Accept: text/plain` (and `?format=`) one file holding all of the
    robot's tools, as the controller loads it (Content-Disposition names it)."""
    if "text/plain" in (accept or ""):
        served = controller_files.robot_file(
            session, robot_id=robot_id, fmt=format, base_url=str(request.base_url)
        )
        headers = {"Content-Disposition": f'attachment; filename="{served.name}"', "Vary": "Accept"}
        return PlainTextResponse(served.text, headers=headers)
    return versions.tool_table(session, robot_id=robot_id, fmt=format)
