"""A calibration's submission, from the authenticated caller to the stored version: the
orchestration POST /v1/tools/{tool_id}/calibrations asks for, in one call.

1. What the solve reads, as held reads on the event loop (a replay needs a session, in a
   worker thread); 2. in a solver process (app.services.solve_pool), the solve with no transaction
   open, then the write under the tool's lock (re-solved there only if what the solve read
   changed). The stored calibration comes back as the JSON the solver process built.
"""

from __future__ import annotations

from typing import NamedTuple

from anyio.to_thread import run_sync

from app.config import get_settings
from app.jsontypes import JsonObject
from app.logs import REQUEST_ID
from app.methods.base import MethodRequest
from app.metrics import CALIBRATIONS
from app.schemas.results import Calibration
from app.security.auth import Principal, transaction_for
from app.services import solve_pool
from app.services.calibrations import presolve, writes
from app.storage.db import loop_engine


class Submission(NamedTuple):
    """The answer to a submission: the stored calibration as JSON (built and validated in
    the solver process, served as it is), or an earlier answer replayed for its
    Idempotency-Key as a model; `replayed` says which was served again."""

    answer: str | Calibration
    replayed: bool


async def submit_calibration(
    *,
    tool_id: str,
    request: MethodRequest,
    raw_body: JsonObject,
    idempotency_key: str | None,
    actor: Principal,
) -> Submission:
    """Solve a submission, grade it and store it as the tool's next version, or replay the
    first answer to its Idempotency-Key; counted in the calibration metrics when stored."""
    if idempotency_key is not None:
        replay = await run_sync(_replay, tool_id, raw_body, idempotency_key, actor)
        if replay is not None:
            return Submission(replay, replayed=True)
    snapshot, ctx = presolve.snapshot_held(loop_engine(), tool_id, actor)
    done = await solve_pool.run(
        writes.solve_and_submit,
        get_settings().database_url,
        tool_id=tool_id,
        request=request,
        snapshot=snapshot,
        ctx=ctx,
        raw_body=raw_body,
        idempotency_key=idempotency_key,
        actor=actor,
        request_id=REQUEST_ID.get(),
    )
    if not done.replayed:
        CALIBRATIONS.labels(done.method, done.status).inc()
    return Submission(done.body, done.replayed)


def _replay(
    tool_id: str, raw_body: JsonObject, idempotency_key: str, actor: Principal
) -> Calibration | None:
    with transaction_for(actor, write=False) as session:
        return writes.replayed(session, tool_id, raw_body, idempotency_key, actor)
