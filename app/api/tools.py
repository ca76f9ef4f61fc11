"""HTTP for tools (CRUD with ETag / If-Match)."""

from __future__ import annotations

from fastapi import APIRouter, Response

from app.api.deps import AdminKey, ReadKey, SessionDep
from app.api.params import DEFAULT_PAGE, Cursor, IfMatch, Limit, PathId
from app.api.shared import page
from app.api.subject_routes import with_etag
from app.schemas.common import Page
from app.schemas.tools import Tool, ToolCreate, ToolUpdate
from app.services.tools import tools

router = APIRouter(tags=["tools"])


@router.post("/v1/robots/{robot_id}/tools", status_code=201, response_model=Tool)
def create_tool(
    robot_id: PathId, body: ToolCreate, response: Response, session: SessionDep, key: AdminKey
) -> Tool:
    """Register a tool on a robot (name and slot unique among the robot's live tools); the
    answer carries the tool's ETag."""
    tool = tools.create_tool(session, robot_id=robot_id, data=body, actor=key)
    return with_etag(response, Tool, tool)


@router.get("/v1/robots/{robot_id}/tools", response_model=Page[Tool])
def list_tools(
    robot_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[Tool]:
    """A robot's live tools, oldest first."""
    items, next_cursor = tools.list_tools(session, robot_id=robot_id, limit=limit, cursor=cursor)
    return page(Tool, items, next_cursor)


@router.get("/v1/tools/{tool_id}", response_model=Tool)
def get_tool(tool_id: PathId, response: Response, session: SessionDep, key: ReadKey) -> Tool:
    """One live tool, with its ETag (it changes with every change to the tool, its versions or
    its activation)."""
    tool = tools.get_tool(session, tool_id)
    return with_etag(response, Tool, tool)


@router.patch("/v1/tools/{tool_id}", response_model=Tool)
def update_tool(
    tool_id: PathId,
    body: ToolUpdate,
    response: Response,
    session: SessionDep,
    key: AdminKey,
    if_match: IfMatch = None,
) -> Tool:
    """Change a tool's fields (tolerance and load merge with what is stored); honours If-Match
    with the tool's ETag."""
    tool = tools.update_tool(session, tool_id=tool_id, data=body, if_match=if_match, actor=key)
    return with_etag(response, Tool, tool)


@router.delete("/v1/tools/{tool_id}", status_code=204)
def archive_tool(tool_id: PathId, session: SessionDep, key: AdminKey) -> Response:
    """Archive a tool: it stops serving a TCP; its calibrations, versions and audit trail are
    kept."""
    tools.archive_tool(session, tool_id=tool_id, actor=key)
    return Response(status_code=204)
