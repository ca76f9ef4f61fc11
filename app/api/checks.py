"""HTTP for TCP checks against a reference point and the re-check after a collision."""

from __future__ import annotations

from fastapi import APIRouter, Response

from app.api.deps import HeldCalibrateKey, run_blocking
from app.api.params import IdempotencyKey, PathId
from app.api.shared import CONTROLLER_FAILURES
from app.schemas.references import CheckCreate, CheckResult
from app.services.checks import recheck

router = APIRouter(tags=["reference points and checks"])


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
    done = await run_blocking(
        recheck.recheck, tool_id=tool_id, data=body, actor=key, idempotency_key=idempotency_key
    )
    if body.capture:
        response.status_code = 201
    if done.replayed:
        response.headers["Idempotent-Replayed"] = "true"
    return done.check
