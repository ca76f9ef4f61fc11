"""HTTP for a tool's versions, activation and the served TCP (JSON or controller text): the
versions' routes are every subject's (app.api.subject_routes), with the tool's documents."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.subject_routes import SubjectRoutes, add_active_route, add_table_route, version_routes
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


add_table_route(
    router,
    TOOL,
    table=versions.tool_table,
    document=ToolTable,
    file=controller_files.robot_file,
    description="Every live tool of a robot with its active TCP, in one answer; tools without "
    "one are\nlisted apart. With `Accept: text/plain` (and `?format=`) one file holding all "
    "of the\nrobot's tools, as the controller loads it (Content-Disposition names it).",
)
