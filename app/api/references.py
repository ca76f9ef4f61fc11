"""HTTP for reference points and TCP checks."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.params import DEFAULT_PAGE, Cursor, Limit
from app.deps import CalibrateKey, ReadKey, SessionDep
from app.schemas.common import Page
from app.schemas.references import CheckCreate, CheckResult, ReferencePoint, ReferencePointCreate
from app.services import checks, references

router = APIRouter(tags=["reference points and checks"])


@router.post(
    "/v1/robots/{robot_id}/reference-points", status_code=201, response_model=ReferencePoint
)
def create_reference_point(
    robot_id: str, body: ReferencePointCreate, session: SessionDep, key: CalibrateKey
) -> object:
    return references.register_reference_point(session, robot_id=robot_id, data=body, actor=key)


@router.get("/v1/robots/{robot_id}/reference-points", response_model=Page[ReferencePoint])
def list_reference_points(
    robot_id: str,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> object:
    items, next_cursor = references.list_reference_points(
        session, robot_id=robot_id, limit=limit, cursor=cursor
    )
    return {"items": items, "next_cursor": next_cursor}


@router.get("/v1/robots/{robot_id}/reference-points/{point_id}", response_model=ReferencePoint)
def get_reference_point(robot_id: str, point_id: str, session: SessionDep, key: ReadKey) -> object:
    return references.get_reference_point(session, robot_id=robot_id, point_id=point_id)


@router.post("/v1/tools/{tool_id}/checks", response_model=CheckResult)
def check_tool(tool_id: str, body: CheckCreate, session: SessionDep, key: CalibrateKey) -> object:
    return checks.run_check(session, tool_id=tool_id, data=body, actor=key)
