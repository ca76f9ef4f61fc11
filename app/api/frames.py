"""HTTP for frames (contract v1.4 "Frames"): CRUD with ETag / If-Match, the active frame a cell
controller reads (ETag, 304), and the versions' routes every subject has
(app.api.subject_routes) with the frame's documents."""

from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Body, Header, Response

from app.api.deps import AdminKey, CalibrateKey, ReadKey, SessionDep
from app.api.params import (
    DEFAULT_PAGE,
    Cursor,
    IdempotencyKey,
    Limit,
    PathId,
)
from app.api.shared import page
from app.api.subject_routes import (
    SubjectRoutes,
    add_active_route,
    add_table_route,
    version_routes,
    with_etag,
)
from app.helpers.etags import IF_MATCH_PATTERN
from app.methods.frame import FrameCalibrationIn, frame_openapi_examples
from app.schemas.common import Page
from app.schemas.frames import (
    ActiveRobotFrame,
    FiducialList,
    FiducialNames,
    FrameCalibration,
    FrameCreate,
    FrameTable,
    FrameUpdate,
    FrameVersion,
    FrameVersionList,
    RobotFrame,
)
from app.services.frames import calibrations, controller_files, fiducials, frames, versions
from app.services.frames.subject import FRAME

router = APIRouter(tags=["frames"])
FrameIfMatch = Annotated[
    str | None,
    Header(pattern=IF_MATCH_PATTERN, description="the frame's ETag (or *); 412 when stale"),
]

# First: the route cell controllers poll is matched before the others.
add_active_route(
    router,
    FRAME,
    document=ActiveRobotFrame,
    serve=controller_files.served_active,
    description="The active frame a cell controller reads (a pose in the robot's base frame; "
    "for a fixed\ntool its stationary TCP), with a strong ETag (If-None-Match -> 304); "
    "`?format=` adds the\ncontroller's own text. With `Accept: text/plain` (and `?format=`) "
    "the file the controller\nloads ($config.dat lines, a RAPID module, a TP program, "
    "UFRAME.CND blocks, a URScript\nfunction, a TMscript line) with a header saying which "
    "version, calibrated when and by\nwhom (Content-Disposition names it).",
)


add_table_route(
    router,
    FRAME,
    table=controller_files.frame_table,
    document=FrameTable,
    file=controller_files.robot_frame_file,
    description="Every live frame of a robot with its active version, in one answer "
    "(`?format=` adds\neach frame's controller text); frames without one are listed apart. "
    "With `Accept:\ntext/plain` (and `?format=`) one file holding all of the robot's frames, "
    "as the\ncontroller loads it (Content-Disposition names it).",
)


@router.post("/v1/robots/{robot_id}/frames", status_code=201, response_model=RobotFrame)
def create_frame(
    robot_id: PathId, body: FrameCreate, response: Response, session: SessionDep, key: AdminKey
) -> RobotFrame:
    """Register a frame on a robot: a base (`kind` base) or a tool standing in the cell
    (`fixed_tool`), its `slot` checked against the frame numbers of the robot's maker or its
    `controller_symbol` against its form (name and slot unique among the robot's live
    frames); the answer carries the frame's ETag."""
    frame = frames.create_frame(session, robot_id=robot_id, data=body, actor=key)
    return with_etag(response, RobotFrame, frame)


@router.get("/v1/robots/{robot_id}/frames", response_model=Page[RobotFrame])
def list_frames(
    robot_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[RobotFrame]:
    """A robot's live frames, oldest first."""
    items, next_cursor = frames.list_frames(session, robot_id=robot_id, limit=limit, cursor=cursor)
    return page(RobotFrame, items, next_cursor)


@router.get("/v1/frames/{frame_id}", response_model=RobotFrame)
def get_frame(
    frame_id: PathId, response: Response, session: SessionDep, key: ReadKey
) -> RobotFrame:
    """One live frame, with its ETag (it changes with every change to the frame, its versions
    or its activation)."""
    frame = frames.get_frame(session, frame_id)
    return with_etag(response, RobotFrame, frame)


@router.patch("/v1/frames/{frame_id}", response_model=RobotFrame)
def update_frame(
    frame_id: PathId,
    body: FrameUpdate,
    response: Response,
    session: SessionDep,
    key: AdminKey,
    if_match: FrameIfMatch = None,
) -> RobotFrame:
    """Change a frame's fields (the tolerance merges with what is stored); honours If-Match
    with the frame's ETag."""
    frame = frames.update_frame(session, frame_id=frame_id, data=body, if_match=if_match, actor=key)
    return with_etag(response, RobotFrame, frame)


@router.delete("/v1/frames/{frame_id}", status_code=204)
def archive_frame(frame_id: PathId, session: SessionDep, key: AdminKey) -> Response:
    """Archive a frame: it stops serving its active frame; its calibrations, versions and
    audit trail are kept."""
    frames.archive_frame(session, frame_id=frame_id, actor=key)
    return Response(status_code=204)


@router.post(
    "/v1/frames/{frame_id}/calibrations",
    status_code=201,
    response_model=FrameCalibration,
    responses={409: {"description": "Idempotency-Key reused with another body"}},
)
def submit_frame_calibration(
    frame_id: PathId,
    body: Annotated[FrameCalibrationIn, Body(openapi_examples=frame_openapi_examples())],
    session: SessionDep,
    key: CalibrateKey,
    idempotency_key: IdempotencyKey = None,
) -> Response:
    """Calibrate a frame from touches by a pointer tool (or enter it by hand: `manual`): its
    method solves it, the frame's tolerance grades it and it is stored as the frame's next
    version, activated when `activate` allows ("auto": within tolerance and within
    max_change_mm of the active frame). Unsolvable input is a 422 naming the touch and what
    to do, and writes nothing. Retry-safe with `Idempotency-Key`."""
    answer, replayed = calibrations.submit(
        session,
        frame_id=frame_id,
        request=body,
        # the body as validated, what a retry must repeat (and what is stored as received)
        raw_body=body.model_dump(mode="json", exclude_unset=True),
        idempotency_key=idempotency_key,
        actor=key,
    )
    headers = {"Idempotent-Replayed": "true"} if replayed else {}
    return Response(
        json.dumps(answer), status_code=201, media_type="application/json", headers=headers
    )


@router.get("/v1/frames/{frame_id}/calibrations", response_model=Page[FrameCalibration])
def list_frame_calibrations(
    frame_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[FrameCalibration]:
    """A frame's calibrations, oldest first, each with its result, version and whether it is
    active."""
    items, next_cursor = calibrations.list_calibrations(
        session, frame_id=frame_id, limit=limit, cursor=cursor
    )
    return page(FrameCalibration, items, next_cursor)


@router.get("/v1/frames/{frame_id}/fiducials", response_model=FiducialList)
def list_fiducials(frame_id: PathId, session: SessionDep, key: ReadKey) -> FiducialList:
    """The points the calibration of the frame's active version kept, each with its name and
    its coordinates in the frame, to be touched again after a move."""
    return fiducials.list_fiducials(session, frame_id=frame_id)


@router.put("/v1/frames/{frame_id}/fiducials", response_model=FiducialList)
def name_fiducials(
    frame_id: PathId, body: FiducialNames, session: SessionDep, key: CalibrateKey
) -> FiducialList:
    """Name the active version's fiducials: one name each, in their order (names unique)."""
    return fiducials.name_fiducials(session, frame_id=frame_id, data=body, actor=key)


router.include_router(
    version_routes(
        SubjectRoutes(
            subject=FRAME,
            document=RobotFrame,
            version=FrameVersion,
            version_list=FrameVersionList,
            version_document=versions.version_document,
            names="frame_",
        )
    )
)
