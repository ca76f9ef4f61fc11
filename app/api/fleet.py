"""The fleet view of every calibrated subject (every tool of every robot at /v1/tools, JSON
or CSV: one route per subject of app.services.subjects, built alike) and a tool's checks
read back.

No `from __future__ import annotations`: each subject's list route is built by
`_fleet_route`, whose parameters' descriptions name the subject, so its annotations are
evaluated where they are written (FastAPI reads them off the function).
"""

from typing import Annotated, TypedDict

from fastapi import APIRouter, Query, Request
from fastapi.responses import Response

from app.api.deps import ReadKey, SessionDep
from app.api.params import Cursor, Limit, PathId
from app.api.shared import page
from app.helpers.pagination import DEFAULT_LIMIT, MAX_LIMIT
from app.schemas.common import ID_PATTERN, NO_CONTROL_PATTERN, Page
from app.schemas.drift import ToolDrift
from app.schemas.fleet import CalibrationStatus, CheckRecord
from app.services.fleet import fleet
from app.services.subjects import IN_FLEET, Served
from app.services.tools import drift
from app.services.tools.subject import TOOL

router = APIRouter(tags=["fleet"])

CSV = "text/csv"
JSON = "application/json"


class Filters(TypedDict):
    cell: str | None
    robot_id: str | None
    q: str | None
    status: str | None
    attention: bool | None


def _fleet_route(served: Served) -> None:
    """GET /v1/<plural>: the subject's fleet rows, a page of JSON or every row as CSV."""
    side = fleet.fleet_of(served).side
    kind, plural, row = served.subject.kind, served.subject.plural, side.row

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
                description=f"prefix of the {kind}'s or robot's name",
            ),
        ] = None,
        status: Annotated[
            CalibrationStatus | None, Query(description="status of the last calibration")
        ] = None,
        attention: Annotated[
            bool | None,
            Query(
                description=f"true: only {plural} that need attention (any code in "
                f"`attention`); false: only {plural} that need none"
            ),
        ] = None,
        limit: Limit = DEFAULT_LIMIT,
        cursor: Cursor = None,
    ) -> Response:
        filters = Filters(cell=cell, robot_id=robot_id, q=q, status=status, attention=attention)
        if CSV in request.headers.get("accept", ""):
            rows: list[fleet.FleetRow] = []
            page_cursor = None
            while True:
                chunk, page_cursor = fleet.list_fleet(
                    session, served, **filters, limit=MAX_LIMIT, cursor=page_cursor
                )
                rows += chunk
                if page_cursor is None:
                    break
            disposition = f'attachment; filename="{side.csv_file}"'
            return Response(
                fleet.fleet_csv(served, rows),
                media_type="text/csv; charset=utf-8",
                headers={"Content-Disposition": disposition},
            )
        items, next_cursor = fleet.list_fleet(
            session, served, **filters, limit=limit, cursor=cursor
        )
        # The rows were validated as they were built: serialised once, not validated again.
        return Response(page(row, items, next_cursor).model_dump_json(), media_type=JSON)

    value = served.subject.value
    list_fleet.__doc__ = (
        f"Every live {kind} of every robot with its robot, cell, active version and {value}, "
        "last\n    calibration, last check and why it needs attention, oldest first, filtered. "
        f"With\n    `Accept: text/csv` every matching {kind} (not one page) as a CSV file, one "
        f"row per {kind}."
    )
    router.add_api_route(
        served.subject.path,
        list_fleet,
        methods=["GET"],
        name=side.operation,
        response_model=Page[row],  # type: ignore[valid-type]
        responses={200: {"content": {CSV: {"schema": {"type": "string"}}}}},
    )


for _served in IN_FLEET:
    _fleet_route(_served)


@router.get("/v1/tools/{tool_id}/checks", response_model=Page[CheckRecord])
def list_checks(
    tool_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_LIMIT,
    cursor: Cursor = None,
) -> Page[CheckRecord]:
    """A tool's checks, newest first: the deviation, the verdict and who checked when."""
    items, next_cursor = fleet.list_checks(
        session, TOOL, subject_id=tool_id, limit=limit, cursor=cursor
    )
    return page(CheckRecord, items, next_cursor)


@router.get("/v1/tools/{tool_id}/drift", response_model=ToolDrift)
def tool_drift(tool_id: PathId, session: SessionDep, key: ReadKey) -> ToolDrift:
    """The tool's drift trends (docs/drift.md): its TCP over the calibrated versions and its
    checks' deviations over time, each a robust line in mm/month with its 95 % interval, and
    when the projection leaves check_mm at 95 % confidence."""
    return drift.tool_drift(session, tool_id)
