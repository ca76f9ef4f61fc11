"""HTTP for planning a touch set and for guided sessions (calibrate touch by touch)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Request, Response
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from app.api.deps import CalibrateKey, HeldCalibrateKey, ReadKey, SessionDep, run_blocking
from app.api.params import DEFAULT_PAGE, Cursor, IdempotencyKey, Limit, PathId
from app.api.shared import CONTROLLER_FAILURES, page
from app.methods.guided import SessionCreate
from app.metrics import CALIBRATIONS
from app.schemas.common import Page
from app.schemas.frame_checks import FrameCheck
from app.schemas.frame_sessions import FrameSession, FrameSessionCreate
from app.schemas.frames import FrameCalibration
from app.schemas.results import Calibration
from app.schemas.sessions import Plan, PlanRequest, Session, SessionFinish
from app.services.sessions import frame_sessions, sessions

router = APIRouter(tags=["guided"])

#: POST /v1/sessions/{id}/poses' body, read by hand: a tool session's or a frame session's.
TOUCH_BODY = {
    "required": True,
    "content": {
        "application/json": {
            "schema": {
                "anyOf": [
                    {"$ref": "#/components/schemas/TouchAdd"},
                    {"$ref": "#/components/schemas/FrameTouchAdd"},
                ],
                "title": "Body",
            }
        }
    },
}

TouchIndex = Annotated[int, Path(ge=0, le=10_000, description="the touch's index, from 0")]


@router.post("/v1/plan", response_model=Plan)
def plan(body: PlanRequest, session: SessionDep, key: ReadKey) -> Plan:
    """Flange poses that determine the TCP best (A-optimal: least expected squared TCP error)
    within the reachable cone around `start`, as full poses in the request's format that put
    the approximate TCP on the point; with `target_sigma_mm` the fewest that reach it (422
    naming the best reachable sigma when 30 cannot). Deterministic."""
    return sessions.plan(session, body)


@router.post("/v1/tools/{tool_id}/sessions", status_code=201, response_model=Session)
def create_session(
    tool_id: PathId, body: SessionCreate, session: SessionDep, key: CalibrateKey
) -> Session:
    """Start a guided calibration: add touches one by one and follow `next_pose` until
    `done`, then finish."""
    return sessions.create_session(session, tool_id=tool_id, data=body, actor=key)


@router.get("/v1/sessions/{session_id}", response_model=Session | FrameSession)
def get_session(session_id: PathId, session: SessionDep, key: ReadKey) -> Session | FrameSession:
    """The session: touches, estimate with its 1-sigma and rms, outliers, next pose, done (a
    frame session's: its touches with their points, next_role, the frame so far)."""
    return sessions.view_any(session, sessions.get_session(session, session_id))


@router.get("/v1/tools/{tool_id}/sessions", response_model=Page[Session])
def list_sessions(
    tool_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[Session]:
    """The tool's guided sessions, newest first: an open one can be resumed."""
    items, next_cursor = sessions.list_sessions(
        session, tool_id=tool_id, limit=limit, cursor=cursor
    )
    return page(Session, items, next_cursor)


@router.post(
    "/v1/sessions/{session_id}/poses",
    response_model=Session | FrameSession,
    responses=CONTROLLER_FAILURES,
    openapi_extra={"requestBody": TOUCH_BODY},
)
async def add_touch(
    session_id: PathId, request: Request, key: HeldCalibrateKey
) -> Session | FrameSession:
    """Add one touch: `pose`, typed in the session's format, or `{"capture": true}`: read
    from the tool's robot's controller (two reads 100 ms apart; 409 `/robot-moving` when
    they differ, 502 when the controller cannot be reached or refuses), converted to the
    session's format and added as a typed pose is. A touch that cannot be read, or that
    makes the set read as a unit or convention mix-up, is refused (422) and the session
    stays as it was; 409 once finished. `touches` says where each came from. A frame
    session's touch (FrameTouchAdd) carries the `role` or `nominal_mm` its method takes
    (`next_role` says which comes next)."""
    raw = await _json(request)
    try:
        data = await run_blocking(sessions.read_touch, session_id=session_id, raw=raw, actor=key)
    except ValidationError as refused:
        raise RequestValidationError(
            [{**e, "loc": ("body", *e["loc"])} for e in refused.errors(include_url=False)]
        ) from None
    return await run_blocking(sessions.add_any_touch, session_id=session_id, data=data, actor=key)


async def _json(request: Request) -> object:
    """The request's JSON body (422 when it is not JSON)."""
    try:
        return await request.json()
    except ValueError as exc:
        raise RequestValidationError(
            [{"type": "json_invalid", "loc": ("body",), "msg": f"JSON decode error: {exc}"}]
        ) from None


@router.delete("/v1/sessions/{session_id}/poses/{index}", response_model=Session | FrameSession)
def delete_touch(
    session_id: PathId, index: TouchIndex, session: SessionDep, key: CalibrateKey
) -> Session | FrameSession:
    """Remove a touch (a miss the session named); later touches move up one index."""
    return sessions.delete_touch(session, session_id=session_id, index=index, actor=key)


@router.post(
    "/v1/sessions/{session_id}/finish",
    status_code=201,
    response_model=Calibration | FrameCalibration | FrameCheck,
)
async def finish_session(
    session_id: PathId,
    response: Response,
    key: HeldCalibrateKey,
    body: SessionFinish | None = None,
    idempotency_key: IdempotencyKey = None,
) -> Calibration | FrameCalibration | FrameCheck:
    """Store the kept touches as a calibration exactly as POST /calibrations would (grading,
    versioning, activation, idempotency, audit); a frame session's as POST /v1/frames/
    {frame_id}/calibrations would (a FrameCalibration); a recheck session's as POST
    /v1/frames/{frame_id}/checks would (a FrameCheck, its correction deployed as the check's
    is). Retry-safe with `Idempotency-Key`."""
    doc, replayed = await run_blocking(
        sessions.finish_request,
        session_id=session_id,
        data=body or SessionFinish(),
        idempotency_key=idempotency_key,
        actor=key,
    )
    if replayed:
        response.headers["Idempotent-Replayed"] = "true"
    if isinstance(doc, FrameCheck):
        return doc
    out = doc if isinstance(doc, Calibration) else FrameCalibration.model_validate(doc)
    if not replayed:
        CALIBRATIONS.labels(out.method, out.status).inc()
    return out


@router.post("/v1/frames/{frame_id}/sessions", status_code=201, response_model=FrameSession)
def create_frame_session(
    frame_id: PathId, body: FrameSessionCreate, session: SessionDep, key: CalibrateKey
) -> FrameSession:
    """Start a guided frame calibration with a pointer tool: add touches one by one (typed,
    or `capture`), each with the role or nominal_mm `next_role` asks for, until `done`, then
    finish (POST /v1/sessions/{id}/finish: a FrameCalibration)."""
    return frame_sessions.create(session, frame_id=frame_id, data=body, actor=key)
