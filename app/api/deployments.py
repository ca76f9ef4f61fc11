"""HTTP for deployments: write a tool's active version into its controller, and the list."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Request, Response

from app.api.deps import HeldCalibrateKey, ReadKey, SessionDep, run_blocking
from app.api.params import DEFAULT_PAGE, Cursor, IdempotencyKey, Limit, PathId
from app.api.shared import page, raw_json_body
from app.schemas.common import Page
from app.schemas.controllers import Deployment, DeploymentIn
from app.services.controllers import deployments

router = APIRouter(tags=["deployments"])

_FAILURES: dict[int | str, dict[str, object]] = {
    502: {
        "description": "the controller is unreachable, refused (its own words in "
        "`controller_message`) or read back something else; `deployment_status` says "
        "whether anything was written (not_written, unverified, mismatch) and the detail says "
        "it in words; `deployment_id` names the recorded attempt",
    }
}


@router.post(
    "/v1/tools/{tool_id}/deployments",
    status_code=201,
    response_model=Deployment,
    responses=_FAILURES,
)
async def deploy_tool(
    tool_id: PathId,
    request: Request,
    response: Response,
    key: HeldCalibrateKey,
    body: Annotated[DeploymentIn | None, Body()] = None,
    idempotency_key: IdempotencyKey = None,
) -> Deployment:
    """Write the tool's active version (and its load) into its robot's controller, read it
    back and compare (within 0.001 mm and 0.001 deg: `verified`, with what the controller
    held before as `previous`). Every attempt is recorded; a failed one answers 502
    `/controller-unreachable`, `/controller-refused` or `/controller-mismatch` with its
    `deployment_id` and `deployment_status`: `not_written` (it failed before the write was sent),
    `unverified` (after: the controller may hold either frame, and the next reconcile round
    records which) or `mismatch`. 409 `/no-active-version`; 422 naming the tool's `slot` or
    `controller_symbol` when the controller cannot address it. The body is `{}` (or none) or
    `{"reason": "..."}`. Calibrate scope; retry-safe with `Idempotency-Key`."""
    raw_body = {} if body is None else await raw_json_body(request)  # no body: as {}
    reason = None if body is None else body.reason
    document, replayed = await run_blocking(
        deployments.deploy,
        tool_id=tool_id,
        actor=key,
        idempotency_key=idempotency_key,
        raw_body=raw_body,
        reason=reason,
    )
    if replayed:
        response.headers["Idempotent-Replayed"] = "true"
    return Deployment.model_validate(document, from_attributes=True)


@router.get("/v1/tools/{tool_id}/deployments", response_model=Page[Deployment])
def list_deployments(
    tool_id: PathId,
    session: SessionDep,
    key: ReadKey,
    limit: Limit = DEFAULT_PAGE,
    cursor: Cursor = None,
) -> Page[Deployment]:
    """A tool's deployments, newest first: verified, not_written, unverified (with what the
    next reconcile round found, `settled`) or mismatch, each with what the controller held
    before and read back, and the reason given."""
    items, next_cursor = deployments.list_deployments(
        session, tool_id=tool_id, limit=limit, cursor=cursor
    )
    return page(Deployment, items, next_cursor)
