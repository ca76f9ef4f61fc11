"""HTTP for planning a touch set and for guided sessions (calibrate touch by touch)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Response

from app.api.deps import CalibrateKey, HeldCalibrateKey, ReadKey, SessionDep, run_blocking
from app.api.params import DEFAULT_PAGE, Cursor, IdempotencyKey, Limit, PathId
from app.api.shared import CONTROLLER_FAILURES, page
from app.methods.guided import SessionCreate
from app.metrics import CALIBRATIONS
from app.schemas.common import Page
from app.schemas.results import Calibration
from app.schemas.sessions import Plan, PlanRequest, Session, SessionFinish, TouchAdd
from app.services.sessions import sessions

router = APIRouter(tags=["guided"])

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


@router.get("/v1/sessions/{session_id}", response_model=Session)
def get_session(session_id: PathId, session: SessionDep, key: ReadKey) -> Session:
    """The session: touches, estimate with its 1-sigma and rms, outliers, next pose, done."""
    return sessions.view(session, sessions.get_session(session, session_id))


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
    "/v1/sessions/{session_id}/poses", response_model=Session, responses=CONTROLLER_FAILURES
)
async def add_touch(session_id: PathId, body: TouchAdd, key: HeldCalibrateKey) -> Session:
    """Add one touch: `pose`, typed in the session's format, or `{"capture": true}`: read
    from the tool's robot's controller (two reads 100 ms apart; 409 `/robot-moving` when
    they differ, 502 when the controller cannot be reached or refuses), converted to the
    session's format and added as a typed pose is. A touch that cannot be read, or that
    makes the set read as a unit or convention mix-up, is refused (422) and the session
    stays as it was; 409 once finished. `touches` says where each came from."""
    return await run_blocking(
        sessions.add_touch_request, session_id=session_id, data=body, actor=key
    )


@router.delete("/v1/sessions/{session_id}/poses/{index}", response_model=Session)
def delete_touch(
    session_id: PathId, index: TouchIndex, session: SessionDep, key: CalibrateKey
) -> Session:
    """Remove a touch (a miss the session named); later touches move up one index."""
    return sessions.delete_touch(session, session_id=session_id, index=index, actor=key)


@router.post("/v1/sessions/{session_id}/finish", status_code=201, response_model=Calibration)
def finish_session(
    session_id: PathId,
    response: Response,
    session: SessionDep,
    key: CalibrateKey,
    body: SessionFinish | None = None,
    idempotency_key: IdempotencyKey = None,
) -> Calibration:
    """Store the kept touches as a calibration exactly as POST /calibrations would (grading,
    versioning, activation, idempotency, audit). Retry-safe with `Idempotency-Key`."""
    doc, replayed = sessions.finish(
        session,
        session_id=session_id,
        data=body or SessionFinish(),
        idempotency_key=idempotency_key,
        actor=key,
    )
    if replayed:
        response.headers["Idempotent-Replayed"] = "true"
    else:
        CALIBRATIONS.labels(doc.method, doc.status).inc()
    return doc
