"""HTTP for reference points and laser devices."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.deps import CalibrateKey, ReadKey, SessionDep
from app.api.params import DEFAULT_PAGE, Cursor, Limit, PathId
from app.api.shared import page
from app.schemas.common import Page
from app.schemas.references import (
    LaserDevice,
    LaserDeviceCreate,
    ReferencePoint,
    ReferencePointCreate,
)
from app.services.references import laser_devices, references

router = APIRouter(tags=["reference points and checks"])


@router.post(
    "/v1/robots/{robot_id}/reference-points", status_code=201, response_model=ReferencePoint
)
def create_reference_point(
    robot_id: PathId, body: ReferencePointCreate, session: SessionDep, key: CalibrateKey
) -> ReferencePoint:
    """Register a fixed point in the robot base frame: as numbers, or touched by a tool whose
    active TCP is trusted."""
    return ReferencePoint.model_validate(
        references.register_reference_point(session, robot_id=robot_id, data=body, actor=key),
        from_attributes=True,
    )


@router.get("/v1/robots/{robot_id}/reference-points", response_model=Page[ReferencePoint])
def list_reference_points(
    robot_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[ReferencePoint]:
    """A robot's reference points, oldest first."""
    items, next_cursor = references.list_reference_points(
        session, robot_id=robot_id, limit=limit, cursor=cursor
    )
    return page(ReferencePoint, items, next_cursor)


@router.get("/v1/robots/{robot_id}/reference-points/{point_id}", response_model=ReferencePoint)
def get_reference_point(
    robot_id: PathId, point_id: PathId, session: SessionDep, key: ReadKey
) -> ReferencePoint:
    """One reference point of a robot."""
    return ReferencePoint.model_validate(
        references.get_reference_point(session, robot_id=robot_id, point_id=point_id),
        from_attributes=True,
    )


@router.post(
    "/v1/robots/{robot_id}/laser-devices",
    status_code=201,
    response_model=LaserDevice,
    tags=["laser devices"],
)
def create_laser_device(
    robot_id: PathId, body: LaserDeviceCreate, session: SessionDep, key: CalibrateKey
) -> LaserDevice:
    """Register a crossed-beam laser device: as numbers, or taught by sweeps of a tool whose
    active TCP is trusted."""
    return LaserDevice.model_validate(
        laser_devices.create_laser_device(session, robot_id=robot_id, data=body, actor=key),
        from_attributes=True,
    )


@router.get(
    "/v1/robots/{robot_id}/laser-devices", response_model=Page[LaserDevice], tags=["laser devices"]
)
def list_laser_devices(
    robot_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[LaserDevice]:
    """A robot's laser devices, oldest first."""
    items, next_cursor = laser_devices.list_laser_devices(
        session, robot_id=robot_id, limit=limit, cursor=cursor
    )
    return page(LaserDevice, items, next_cursor)


@router.get(
    "/v1/robots/{robot_id}/laser-devices/{device_id}",
    response_model=LaserDevice,
    tags=["laser devices"],
)
def get_laser_device(
    robot_id: PathId, device_id: PathId, session: SessionDep, key: ReadKey
) -> LaserDevice:
    """One laser device of a robot."""
    return LaserDevice.model_validate(
        laser_devices.get_laser_device(session, robot_id=robot_id, device_id=device_id),
        from_attributes=True,
    )
