"""HTTP for calibrations: submit (with Idempotency-Key), list, read."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Request, Response

from app.api.deps import HeldCalibrateKey, ReadKey, SessionDep
from app.api.params import DEFAULT_PAGE, Cursor, IdempotencyKey, Limit, PathId
from app.api.shared import page, raw_json_body
from app.methods import openapi_examples
from app.methods.requests import CalibrationRequest
from app.schemas.common import Page
from app.schemas.results import Calibration, CalibrationDetail
from app.services.calibrations import stored, submissions

router = APIRouter(tags=["calibrations"])


@router.post("/v1/tools/{tool_id}/calibrations", status_code=201, response_model=Calibration)
async def submit_calibration(
    tool_id: PathId,
    body: Annotated[CalibrationRequest, Body(openapi_examples=openapi_examples())],
    request: Request,
    response: Response,
    key: HeldCalibrateKey,
    idempotency_key: IdempotencyKey = None,
) -> Calibration | Response:
    """Solve a submission with its method, grade it against the tool's tolerance and store it as
    the tool's next version. Activated when `activate` allows ("auto": within tolerance and
    within max_change_mm of the active TCP). Unsolvable input is a 422 and writes nothing;
    so are poses that fit far better under another unit or convention than the one sent
    (`convention-mismatch`, with the `suggestion` to resend). Retry-safe with
    `Idempotency-Key`."""
    raw_body = await raw_json_body(request)
    answer, replayed = await submissions.submit_calibration(
        tool_id=tool_id,
        request=body,
        raw_body=raw_body,
        idempotency_key=idempotency_key,
        actor=key,
    )
    headers = {"Idempotent-Replayed": "true"} if replayed else {}
    if isinstance(answer, Calibration):  # a replay read back: served through the model
        response.headers.update(headers)
        return answer
    # Built and validated in the solver process: served as it came.
    return Response(answer, status_code=201, media_type="application/json", headers=headers)


@router.get("/v1/tools/{tool_id}/calibrations", response_model=Page[Calibration])
def list_calibrations(
    tool_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[Calibration]:
    """A tool's calibrations, oldest first, each with its result, version and whether it is
    active."""
    items, next_cursor = stored.list_calibrations(
        session, tool_id=tool_id, limit=limit, cursor=cursor
    )
    return page(Calibration, items, next_cursor)


@router.get("/v1/calibrations/{calibration_id}", response_model=CalibrationDetail)
def get_calibration(calibration_id: PathId, session: SessionDep, key: ReadKey) -> CalibrationDetail:
    """One calibration with its result and the submission exactly as received."""
    return stored.get_calibration(session, calibration_id=calibration_id)
