"""HTTP for robots."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response

from app.api.deps import AdminKey, ReadKey, SessionDep
from app.api.params import DEFAULT_PAGE, Cursor, Limit, PathId
from app.api.shared import page
from app.schemas.common import NO_CONTROL_PATTERN, Page
from app.schemas.robots import Robot, RobotCreate, RobotUpdate
from app.services.robots import robots

router = APIRouter(prefix="/v1/robots", tags=["robots"])


@router.post("", status_code=201, response_model=Robot)
def create_robot(body: RobotCreate, session: SessionDep, key: AdminKey) -> Robot:
    """Register a robot (its name unique among live robots), with kinematics when the `joints`
    pose format will be used."""
    return Robot.model_validate(
        robots.create_robot(session, data=body, actor=key), from_attributes=True
    )


@router.get("", response_model=Page[Robot])
def list_robots(
    session: SessionDep,
    key: ReadKey,
    cell: Annotated[str | None, Query(max_length=200, pattern=NO_CONTROL_PATTERN)] = None,
    name: Annotated[str | None, Query(max_length=200, pattern=NO_CONTROL_PATTERN)] = None,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[Robot]:
    """Live robots, oldest first; filter by cell or name."""
    items, next_cursor = robots.list_robots(
        session, cell=cell, name=name, limit=limit, cursor=cursor
    )
    return page(Robot, items, next_cursor)


@router.get("/{robot_id}", response_model=Robot)
def get_robot(robot_id: PathId, session: SessionDep, key: ReadKey) -> Robot:
    """One live robot (404 `/archived` once deleted)."""
    return Robot.model_validate(robots.get_robot(session, robot_id), from_attributes=True)


@router.patch("/{robot_id}", response_model=Robot)
def update_robot(robot_id: PathId, body: RobotUpdate, session: SessionDep, key: AdminKey) -> Robot:
    """Change a robot's fields; only the fields sent change."""
    return Robot.model_validate(
        robots.update_robot(session, robot_id=robot_id, data=body, actor=key), from_attributes=True
    )


@router.delete("/{robot_id}", status_code=204)
def archive_robot(robot_id: PathId, session: SessionDep, key: AdminKey) -> Response:
    """Archive a robot and its tools: they leave lists and stop serving a TCP; their history is
    kept."""
    robots.archive_robot(session, robot_id=robot_id, actor=key)
    return Response(status_code=204)
