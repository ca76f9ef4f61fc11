"""HTTP for reference points and TCP checks."""

from __future__ import annotations

from fastapi import APIRouter

from app import models
from app.api.params import DEFAULT_PAGE, Cursor, Limit, PathId
from app.deps import CalibrateKey, ReadKey, SessionDep
from app.schemas.common import Page
from app.schemas.references import (
    CheckCreate,
    CheckResult,
    LaserDevice,
    LaserDeviceCreate,
    ReferencePoint,
    ReferencePointCreate,
)
from app.services import checks, laser_devices, references

router = APIRouter(tags=["reference points and checks"])


@router.post(
    "/v1/robots/{robot_id}/reference-points", status_code=201, response_model=ReferencePoint
)
def create_reference_point(
    robot_id: PathId, body: ReferencePointCreate, session: SessionDep, key: CalibrateKey
) -> object:
    """Register a fixed point in the robot base frame: as numbers, or touched by a tool whose
    active TCP is trusted."""
    return references.register_reference_point(session, robot_id=robot_id, data=body, actor=key)


@router.get("/v1/robots/{robot_id}/reference-points", response_model=Page[ReferencePoint])
def list_reference_points(
    robot_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> object:
    """A robot's reference points, oldest first."""
    items, next_cursor = references.list_robot_rows(
        session, models.ReferencePoint, robot_id=robot_id, limit=limit, cursor=cursor
    )
    return {"items": items, "next_cursor": next_cursor}


@router.get("/v1/robots/{robot_id}/reference-points/{point_id}", response_model=ReferencePoint)
def get_reference_point(
    robot_id: PathId, point_id: PathId, session: SessionDep, key: ReadKey
) -> object:
    """One reference point of a robot."""
    return references.get_reference_point(session, robot_id=robot_id, point_id=point_id)


@router.post("/v1/tools/{tool_id}/checks", response_model=CheckResult)
def check_tool(
    tool_id: PathId, body: CheckCreate, session: SessionDep, key: CalibrateKey
) -> object:
    """Touch a reference point with the active TCP and measure the drift against the tool's
    check_mm; the active TCP is not changed. `deviation_flange_mm` is how the tool moved
    (new minus active, flange frame) and `summary` says it in a sentence. Poses that fit
    far better under another unit or convention are refused (`convention-mismatch`)."""
    return checks.run_check(session, tool_id=tool_id, data=body, actor=key)


@router.post(
    "/v1/robots/{robot_id}/laser-devices",
    status_code=201,
    response_model=LaserDevice,
    tags=["laser devices"],
)
def create_laser_device(
    robot_id: PathId, body: LaserDeviceCreate, session: SessionDep, key: CalibrateKey
) -> object:
    """Register a crossed-beam laser device: as numbers, or taught by sweeps of a tool whose
    active TCP is trusted."""
    return laser_devices.create_laser_device(session, robot_id=robot_id, data=body, actor=key)


@router.get(
    "/v1/robots/{robot_id}/laser-devices", response_model=Page[LaserDevice], tags=["laser devices"]
)
def list_laser_devices(
    robot_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> object:
    """A robot's laser devices, oldest first."""
    items, next_cursor = references.list_robot_rows(
        session, models.LaserDevice, robot_id=robot_id, limit=limit, cursor=cursor
    )
    return {"items": items, "next_cursor": next_cursor}


@router.get(
    "/v1/robots/{robot_id}/laser-devices/{device_id}",
    response_model=LaserDevice,
    tags=["laser devices"],
)
def get_laser_device(
    robot_id: PathId, device_id: PathId, session: SessionDep, key: ReadKey
) -> object:
    """One laser device of a robot."""
    return laser_devices.get_laser_device(session, robot_id=robot_id, device_id=device_id)
