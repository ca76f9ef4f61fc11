"""HTTP for a frame's re-check after a move (contract v1.4 "After a move: re-register")."""

from __future__ import annotations

from fastapi import APIRouter, Response

from app.api.deps import HeldCalibrateKey, run_blocking
from app.api.params import IdempotencyKey, PathId
from app.schemas.frame_checks import FrameCheck, FrameCheckCreate
from app.services.checks import frame_recheck as checks

router = APIRouter(tags=["frames"])


@router.post("/v1/frames/{frame_id}/checks", status_code=201, response_model=FrameCheck)
async def check_frame(
    frame_id: PathId,
    body: FrameCheckCreate,
    response: Response,
    key: HeldCalibrateKey,
    idempotency_key: IdempotencyKey = None,
) -> FrameCheck:
    """Touch three or more of the frame's stored fiducials again (GET
    /v1/frames/{frame_id}/fiducials) after a move: the shift is the best rigid fit of the
    stored fiducials to the new touches, with its uncertainty; `deviations` says how far each
    fiducial moved, in the frame's axes and in words. A touch far from the fiducial it names
    is refused naming the stored fiducial it is near, before any shift is computed. Judged at
    the fiducials: within check_mm `within_tolerance`; with `"correct": "within_limits"`, a
    largest deviation past check_mm and none past max_correction_mm is `corrected`: a new
    version carried by the shift, activated with kind `check_correction` and `reason` (with
    `"scope": "robot"` every frame and reference point of the robot too, in one
    transaction); otherwise `needs_recalibration`, nothing changed (the fleet's
    `check_failed`). Retry-safe with `Idempotency-Key`: concurrent sends make one version."""
    done = await run_blocking(
        checks.check_frame,
        frame_id=frame_id,
        data=body,
        actor=key,
        idempotency_key=idempotency_key,
    )
    if done.replayed:
        response.headers["Idempotent-Replayed"] = "true"
    return done.check
