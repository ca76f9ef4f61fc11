"""HTTP for a robot's controller: its connection, and reconciling what it holds."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response

from app.api.deps import AdminKey, HeldCalibrateKey, HeldReadKey, ReadKey, SessionDep, run_blocking
from app.api.params import PathId
from app.api.shared import CONTROLLER_FAILURES
from app.errors import NoControllerSet
from app.schemas.controllers import Controller, ControllerIn, ControllerPose, Reconciliation
from app.services.controllers import capture, reconcile
from app.services.robots import connection
from app.vendors.registry import REFUSAL_EXAMPLES
from app.words import PoseFormat

router = APIRouter(tags=["controllers"])


@router.put("/v1/robots/{robot_id}/controller", response_model=Controller)
def put_controller(
    robot_id: PathId, body: ControllerIn, session: SessionDep, key: AdminKey
) -> Controller:
    """Set how tcpcal reaches the robot's controller. `port` defaults to the protocol's;
    `password` is write-only and stored encrypted under TCPCAL_SECRET_KEY (422 while it is
    unset): left out, the stored one is kept; null removes it. The answer says
    `has_password`, never the password."""
    controller = connection.put_controller(
        session, robot_id=robot_id, data=body, fields_sent=body.model_fields_set, actor=key
    )
    return Controller.model_validate(
        connection.controller_document(controller), from_attributes=True
    )


@router.get("/v1/robots/{robot_id}/controller", response_model=Controller)
def get_controller(robot_id: PathId, session: SessionDep, key: ReadKey) -> Controller:
    """How tcpcal reaches the robot's controller (404 `/no-controller` when it has none)."""
    controller = connection.get_controller(session, robot_id, missing=NoControllerSet)
    return Controller.model_validate(
        connection.controller_document(controller), from_attributes=True
    )


@router.delete("/v1/robots/{robot_id}/controller", status_code=204)
def delete_controller(robot_id: PathId, session: SessionDep, key: AdminKey) -> Response:
    """Forget the robot's controller connection; its deployments stay in the history."""
    connection.delete_controller(session, robot_id=robot_id, actor=key)
    return Response(status_code=204)


#: The pose read's description (its docstring but for the makers' example of a refusal,
#: read from their declarations: app.vendors.registry.REFUSAL_EXAMPLES).
_POSE_READ = (
    "Where the robot's flange is now, in its base frame, read from its controller twice at\n"
    "least 100 ms apart within its timeout_s: 409 `/robot-moving` when the reads differ by\n"
    "more than 0.01 mm or 0.01 deg (nothing is kept), 502 `/controller-unreachable` or\n"
    f"`/controller-refused` (the controller's words, e.g. {REFUSAL_EXAMPLES}). With\n"
    "the joints, the tool the robot moves by (`live_tool`) and every value read as the\n"
    "controller printed it. Calibrate scope (it is how a touch is captured)."
)


@router.get(
    "/v1/robots/{robot_id}/controller/pose",
    response_model=ControllerPose,
    responses=CONTROLLER_FAILURES,
    description=_POSE_READ,
)
async def read_controller_pose(
    robot_id: PathId,
    key: HeldCalibrateKey,
    fmt: Annotated[PoseFormat, Query(alias="format")] = "matrix",
) -> ControllerPose:
    """Where the robot's flange is now, read twice from its controller (`_POSE_READ`)."""
    return await run_blocking(capture.controller_pose, robot_id=robot_id, fmt=fmt, actor=key)


@router.post("/v1/robots/{robot_id}/reconcile", response_model=Reconciliation)
async def reconcile_robot(robot_id: PathId, key: HeldReadKey) -> Reconciliation:
    """Read every live tool's frame from the robot's controller and compare it with the
    tool's active version: `in_sync` within 0.01 mm and 0.01 deg, else `drifted`;
    `unreachable` when it cannot be read. The robot's state is the worst of its tools'.
    Each change of a tool's state is an audit event. Read scope."""
    reconciled = await run_blocking(reconcile.reconcile_robot, robot_id=robot_id, actor=key)
    assert reconciled is not None  # None only when cancelled, which a request never is
    return reconciled
