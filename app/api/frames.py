"""HTTP for frames (contract v1.4 "Frames"): CRUD with ETag / If-Match, the active frame a cell
controller reads (ETag, 304), and the versions' routes every subject has
(app.api.subject_routes) with the frame's documents."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Header, Request, Response

from app.api.deps import AdminKey, ReadKey, SessionDep, label_request
from app.api.params import DEFAULT_PAGE, IF_NONE_MATCH, Cursor, Limit, PathId, RawParam
from app.api.shared import page
from app.api.subject_routes import SubjectRoutes, version_routes
from app.helpers.etags import IF_MATCH_PATTERN
from app.schemas.common import ID_PATTERN, Page
from app.schemas.frames import (
    ActiveRobotFrame,
    FrameCreate,
    FrameUpdate,
    FrameVersion,
    FrameVersionList,
    RobotFrame,
)
from app.services.frames import frames, versions
from app.services.frames.subject import FRAME
from app.services.lifecycle.versions import etag

router = APIRouter(tags=["frames"])
FrameIfMatch = Annotated[
    str | None,
    Header(pattern=IF_MATCH_PATTERN, description="the frame's ETag (or *); 412 when stale"),
]

#: The hot read's path parameter, read by hand (see RawParam).
FRAME_ID = RawParam(
    "path",
    "frame_id",
    "Frame Id",
    "an id this service issued (1-64 of A-Za-z0-9_-); take it from GET /v1/frames",
    description="resource id",
    pattern=ID_PATTERN,
)


# First: the route cell controllers poll is matched before the others.
@router.get(
    "/v1/frames/{frame_id}/frame",
    response_model=ActiveRobotFrame,
    responses={304: {"description": "not modified (If-None-Match)"}},
    openapi_extra={"parameters": [p.openapi() for p in (FRAME_ID, IF_NONE_MATCH)]},
)
async def get_active_frame(request: Request) -> Response:
    """The active frame a cell controller reads (a pose in the robot's base frame; for a fixed
    tool its stationary TCP), with a strong ETag (If-None-Match -> 304)."""
    frame_id = FRAME_ID.read(request)
    assert frame_id is not None  # a path parameter
    # On the event loop: the key check and the read are one indexed statement.
    key, document, tag = versions.served_frame_for_key(
        authorization=request.headers.get("authorization"),
        frame_id=frame_id,
        if_none_match=IF_NONE_MATCH.read(request),
    )
    label_request(request, key)
    headers = {"ETag": tag}
    if document is None:
        return Response(status_code=304, headers=headers)
    return Response(document.model_dump_json(), media_type="application/json", headers=headers)


@router.post("/v1/robots/{robot_id}/frames", status_code=201, response_model=RobotFrame)
def create_frame(
    robot_id: PathId, body: FrameCreate, response: Response, session: SessionDep, key: AdminKey
) -> RobotFrame:
    """Register a frame on a robot: a base (`kind` base) or a tool standing in the cell
    (`fixed_tool`), its `slot` checked against the frame numbers of the robot's maker or its
    `controller_symbol` against its form (name and slot unique among the robot's live
    frames); the answer carries the frame's ETag."""
    frame = frames.create_frame(session, robot_id=robot_id, data=body, actor=key)
    response.headers["ETag"] = etag(frame)
    return RobotFrame.model_validate(frame, from_attributes=True)


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
    response.headers["ETag"] = etag(frame)
    return RobotFrame.model_validate(frame, from_attributes=True)


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
    response.headers["ETag"] = etag(frame)
    return RobotFrame.model_validate(frame, from_attributes=True)


@router.delete("/v1/frames/{frame_id}", status_code=204)
def archive_frame(frame_id: PathId, session: SessionDep, key: AdminKey) -> Response:
    """Archive a frame: it stops serving its active frame; its calibrations, versions and
    audit trail are kept."""
    frames.archive_frame(session, frame_id=frame_id, actor=key)
    return Response(status_code=204)


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
