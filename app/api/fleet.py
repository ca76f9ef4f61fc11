"""The fleet view (every tool of every robot, JSON or CSV) and a tool's checks read back."""

from __future__ import annotations

from typing import Annotated, TypedDict

from fastapi import APIRouter, Query, Request
from fastapi.responses import Response

from app.api.deps import ReadKey, SessionDep
from app.api.params import Cursor, Limit, PathId
from app.api.shared import page
from app.helpers.pagination import DEFAULT_LIMIT, MAX_LIMIT
from app.schemas.common import ID_PATTERN, NO_CONTROL_PATTERN, Page
from app.schemas.drift import ToolDrift
from app.schemas.fleet import CalibrationStatus, CheckRecord, FleetTool
from app.services.fleet import fleet
from app.services.tools import drift

router = APIRouter(tags=["fleet"])

CSV = "text/csv"
JSON = "application/json"


class Filters(TypedDict):
    cell: str | None
    robot_id: str | None
    q: str | None
    status: str | None
    attention: bool | None


@router.get(
    "/v1/tools",
    response_model=Page[FleetTool],
    responses={200: {"content": {CSV: {"schema": {"type": "string"}}}}},
)
def list_fleet(
    request: Request,
    session: SessionDep,
    key: ReadKey,
    cell: Annotated[
        str | None,
        Query(max_length=200, pattern=NO_CONTROL_PATTERN, description="the robots' cell"),
    ] = None,
    robot_id: Annotated[str | None, Query(pattern=ID_PATTERN)] = None,
    q: Annotated[
        str | None,
        Query(
            max_length=200,
            pattern=NO_CONTROL_PATTERN,
            description="prefix of the tool's or robot's name",
        ),
    ] = None,
    status: Annotated[
        CalibrationStatus | None, Query(description="status of the last calibration")
    ] = None,
    attention: Annotated[
        bool | None,
        Query(
            description="true: only tools that need attention (any code in `attention`); "
            "false: only tools that need none"
        ),
    ] = None,
    limit: Limit = DEFAULT_LIMIT,
    cursor: Cursor = None,
) -> Response:
    """Every live tool of every robot with its robot, cell, active version and TCP, last
    calibration, last check and why it needs attention, oldest first, filtered. With
    `Accept: text/csv` every matching tool (not one page) as a CSV file, one row per tool."""
    filters = Filters(cell=cell, robot_id=robot_id, q=q, status=status, attention=attention)
    if CSV in request.headers.get("accept", ""):
        rows: list[FleetTool] = []
        page_cursor = None
        while True:
            chunk, page_cursor = fleet.list_fleet(
                session, **filters, limit=MAX_LIMIT, cursor=page_cursor
            )
            rows += chunk
            if page_cursor is None:
                break
        return Response(
            fleet.fleet_csv(rows),
            media_type="text/csv; charset=utf-8",
            headers={"Content-Disposition": 'attachment; filename="tcpcal-fleet.csv"'},
        )
    items, next_cursor = fleet.list_fleet(session, **filters, limit=limit, cursor=cursor)
    # The rows were validated as they were built: serialised once, not validated again.
    return Response(page(FleetTool, items, next_cursor).model_dump_json(), media_type=JSON)


@router.get("/v1/tools/{tool_id}/checks", response_model=Page[CheckRecord])
def list_checks(
    tool_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_LIMIT,
    cursor: Cursor = None,
) -> Page[CheckRecord]:
    """A tool's checks, newest first: the deviation, the verdict and who checked when."""
    items, next_cursor = fleet.list_checks(session, tool_id=tool_id, limit=limit, cursor=cursor)
    return page(CheckRecord, items, next_cursor)


@router.get("/v1/tools/{tool_id}/drift", response_model=ToolDrift)
def tool_drift(tool_id: PathId, session: SessionDep, key: ReadKey) -> ToolDrift:
    """The tool's drift trends (docs/drift.md): its TCP over the calibrated versions and its
    checks' deviations over time, each a robust line in mm/month with its 95 % interval, and
    when the projection leaves check_mm at 95 % confidence."""
    return drift.tool_drift(session, tool_id)
