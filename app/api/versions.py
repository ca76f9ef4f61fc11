"""HTTP for a tool's versions, activation and the served TCP (JSON or controller text): the
versions' routes are every subject's (app.api.subject_routes), with the tool's documents."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import PlainTextResponse

from app.api.deps import ReadKey, SessionDep
from app.api.params import (
    AcceptHeader,
    FormatQuery,
    PathId,
)
from app.api.subject_routes import SubjectRoutes, add_active_route, version_routes
from app.schemas.tools import ActiveTcp, Tool, ToolTable, Version, VersionList
from app.services.tools import active_tcp, controller_files, versions
from app.services.tools.subject import TOOL

router = APIRouter(tags=["versions"])

# First: the route cell controllers poll is matched before the others.
add_active_route(
    router,
    TOOL,
    document=ActiveTcp,
    serve=active_tcp.active_tcp,
    description="The active TCP a cell controller reads, with a strong ETag (If-None-Match "
    "-> 304);\n`?format=` adds the controller's own text. With `Accept: text/plain` (and "
    "`?format=`) the\nfile the controller loads (a RAPID module, $config.dat lines, a TP "
    "program, TOOL.CND, a\nURScript function, a TMscript line) with a header saying which "
    "version, calibrated when\nand by whom (Content-Disposition names it).",
)


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
