"""HTTP for reference points and TCP checks."""

from __future__ import annotations

from fastapi import APIRouter, Response
from starlette.concurrency import run_in_threadpool

from app.api.deps import CalibrateKey, HeldCalibrateKey, ReadKey, SessionDep
from app.api.params import DEFAULT_PAGE, Cursor, IdempotencyKey, Limit, PathId
from app.api.shared import CONTROLLER_FAILURES, page
from app.schemas.common import Page
from app.schemas.references import (
    CheckCreate,
    CheckResult,
    LaserDevice,
    LaserDeviceCreate,
    ReferencePoint,
    ReferencePointCreate,
)
from app.services.calibrate import laser_devices, recheck, references

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


#: A captured check (the v1.3 re-check) records a touch and may create a version: 201.
_CHECK_RESPONSES: dict[int | str, dict[str, object]] = {
    **CONTROLLER_FAILURES,
    201: {
        "description": 'a captured check ("capture": true), with its correction if any',
        "model": CheckResult,
    },
}


@router.post("/v1/tools/{tool_id}/checks", response_model=CheckResult, responses=_CHECK_RESPONSES)
async def check_tool(
    tool_id: PathId,
    body: CheckCreate,
    response: Response,
    key: HeldCalibrateKey,
    idempotency_key: IdempotencyKey = None,
) -> CheckResult:
    """Touch a reference point with the active TCP and measure the drift against the tool's
    check_mm. `deviation_flange_mm` is how the tool moved (new minus active, flange frame)
    and `summary` says it in a sentence. Poses that fit far better under another unit or
    convention are refused (`convention-mismatch`). `{"capture": true}` in place of `format`
    and `poses` reads the one touch from the robot's controller (201): 409 `/robot-moving`
    when two reads 100 ms apart differ, 502 when the controller cannot be reached or
    refuses. With `"correct": "within_limits"` a captured deviation beyond check_mm and
    within the tool's max_correction_mm is corrected: a version by xyz_reference from the
    touch (orientation kept), activated with kind `check_correction` and `reason`, then
    deployed and read back (`deploy`, default true); `correction` says what was done and
    `verdict` what came of it (a failed deployment leaves the new version active and the
    controller flagged: `deployment_failed`). Beyond max_correction_mm nothing changes
    (`recalibrate`). Retry-safe with `Idempotency-Key`."""
    done = await run_in_threadpool(
        lambda: recheck.recheck(
            tool_id=tool_id, data=body, actor=key, idempotency_key=idempotency_key
        )
    )
    if body.capture:
        response.status_code = 201
    if done.replayed:
        response.headers["Idempotent-Replayed"] = "true"
    return done.check


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
