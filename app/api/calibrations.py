"""HTTP for calibrations: submit (with Idempotency-Key), list, read."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Header, Request, Response
from starlette.concurrency import run_in_threadpool

from app import solve_pool
from app.api.params import DEFAULT_PAGE, Cursor, Limit, PathId
from app.auth import Principal, act_for, authenticate_held
from app.config import get_settings
from app.db import loop_engine, session_scope
from app.deps import ReadKey, SessionDep
from app.errors import InvalidInput
from app.jsontypes import JsonObject
from app.logs import REQUEST_ID
from app.methods import openapi_examples
from app.metrics import CALIBRATIONS
from app.middleware import KEY_NAME
from app.schemas.calibrations import CalibrationRequest
from app.schemas.common import Page
from app.schemas.results import Calibration, CalibrationDetail
from app.services import calibrate

router = APIRouter(tags=["calibrations"])

IdempotencyKey = Annotated[
    str | None,
    Header(
        min_length=1,
        max_length=200,
        description="retry-safe submissions: same key and body -> the first response",
    ),
]


async def raw_json_body(request: Request) -> JsonObject:
    """The body as received, before validation: the JSON FastAPI parsed to validate it, which
    the request keeps (parsing the bytes again cost 30 us of the event loop per calibration)."""
    parsed = await request.json()
    if not isinstance(parsed, dict):
        raise InvalidInput("validation", "the body must be a JSON object", loc=("body",))
    return parsed


@router.post("/v1/tools/{tool_id}/calibrations", status_code=201, response_model=Calibration)
async def submit_calibration(
    tool_id: PathId,
    body: Annotated[CalibrationRequest, Body(openapi_examples=openapi_examples())],
    request: Request,
    response: Response,
    idempotency_key: IdempotencyKey = None,
    authorization: Annotated[str | None, Header(include_in_schema=False)] = None,
) -> object:
    """Solve a submission with its method, grade it against the tool's tolerance and store it as
    the tool's next version. Activated when `activate` allows ("auto": within tolerance and
    within max_change_mm of the active TCP). Unsolvable input is a 422 and writes nothing;
    so are poses that fit far better under another unit or convention than the one sent
    (`convention-mismatch`, with the `suggestion` to resend). Retry-safe with
    `Idempotency-Key`."""
    raw_body = await raw_json_body(request)
    # 1. Who, and what the solve reads: held reads on the event loop (a replay needs a session
    # in a worker thread); 2. in a solver process, the solve with no transaction open, then
    # the write under the tool's lock (re-solved there only if what the solve read changed).
    key = authenticate_held(loop_engine(), authorization, required="calibrate")
    request.scope[KEY_NAME] = key.name
    if idempotency_key is not None:
        replay = await run_in_threadpool(_replay, tool_id, raw_body, idempotency_key, key)
        if replay is not None:
            response.headers["Idempotent-Replayed"] = "true"
            return replay
    snapshot, ctx = calibrate.snapshot_held(loop_engine(), tool_id, key)
    done = await solve_pool.run(
        calibrate.solve_and_submit,
        get_settings().database_url,
        tool_id=tool_id,
        request=body,
        snapshot=snapshot,
        ctx=ctx,
        raw_body=raw_body,
        idempotency_key=idempotency_key,
        actor=key,
        request_id=REQUEST_ID.get(),
    )
    if done.replayed:
        headers = {"Idempotent-Replayed": "true"}
    else:
        headers = {}
        CALIBRATIONS.labels(done.method, done.status).inc()
    return Response(done.body, status_code=201, media_type="application/json", headers=headers)


def _replay(
    tool_id: str, raw_body: JsonObject, idempotency_key: str, key: Principal
) -> Calibration | None:
    with session_scope(write=False) as session:
        act_for(session, key)
        return calibrate.replayed(session, tool_id, raw_body, idempotency_key, key)


@router.get("/v1/tools/{tool_id}/calibrations", response_model=Page[Calibration])
def list_calibrations(
    tool_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> object:
    """A tool's calibrations, oldest first, each with its result, version and whether it is
    active."""
    items, next_cursor = calibrate.list_calibrations(
        session, tool_id=tool_id, limit=limit, cursor=cursor
    )
    return {"items": items, "next_cursor": next_cursor}


@router.get("/v1/calibrations/{calibration_id}", response_model=CalibrationDetail)
def get_calibration(calibration_id: PathId, session: SessionDep, key: ReadKey) -> object:
    """One calibration with its result and the submission exactly as received."""
    return calibrate.get_calibration(session, calibration_id=calibration_id)
