"""HTTP for deployments: write a subject's active version into its controller, and the list,
served for every subject that declares a controller side by one router factory
(`deployments_router`), under its path and with its own schema and words."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, TypeVar

from fastapi import APIRouter, Body, Request, Response
from pydantic import BaseModel

from app.api.deps import HeldCalibrateKey, ReadKey, SessionDep, run_blocking
from app.api.params import DEFAULT_PAGE, Cursor, IdempotencyKey, Limit, PathId
from app.api.shared import page, raw_json_body
from app.schemas.common import Page
from app.schemas.controllers import DeploymentIn
from app.services.controllers import deployments
from app.services.frames.subject import FRAME
from app.services.lifecycle.subject import AnySubject
from app.services.tools.subject import TOOL

_FAILURES: dict[int | str, dict[str, object]] = {
    502: {
        "description": "the controller is unreachable, refused (its own words in "
        "`controller_message`) or read back something else; `deployment_status` says "
        "whether anything was written (not_written, unverified, mismatch) and the detail says "
        "it in words; `deployment_id` names the recorded attempt",
    }
}


Endpoint = TypeVar("Endpoint", bound=Callable[..., object])


@dataclass(frozen=True)
class Words:
    """A subject's deployment routes as they are named and described: the operations' names
    (their operationId and summary) and descriptions."""

    deploy_name: str
    deploy: str
    list_name: str
    list: str
    #: the deploy route's failures beside its 502
    failures: tuple[tuple[int, str], ...] = ()


def _with_id(endpoint: Endpoint, key: str, name: str, doc: str) -> Endpoint:
    """The endpoint with the subject's id as its first parameter, named by the subject's key
    (its path parameter: "tool_id"), and the operation's name and description."""
    signature = inspect.signature(endpoint)
    first = inspect.Parameter(key, inspect.Parameter.POSITIONAL_OR_KEYWORD, annotation=PathId)
    endpoint.__signature__ = signature.replace(  # type: ignore[attr-defined]
        parameters=[first, *signature.parameters.values()]
    )
    endpoint.__name__ = name
    endpoint.__doc__ = doc
    return endpoint


def deployments_router(subject: AnySubject, words: Words) -> APIRouter:
    """POST and GET {subject.path}/{id}/deployments for a subject with a controller side."""
    side = deployments.side_of(subject)
    schema = side.deployment_schema
    id_name = subject.key
    router = APIRouter(tags=["deployments"])

    async def deploy(
        request: Request,
        response: Response,
        key: HeldCalibrateKey,
        body: Annotated[DeploymentIn | None, Body()] = None,
        idempotency_key: IdempotencyKey = None,
        **ids: str,
    ) -> BaseModel:
        raw_body = {} if body is None else await raw_json_body(request)  # no body: as {}
        reason = None if body is None else body.reason
        document, replayed = await run_blocking(
            deployments.deploy,
            subject,
            subject_id=ids[id_name],
            actor=key,
            idempotency_key=idempotency_key,
            raw_body=raw_body,
            reason=reason,
        )
        if replayed:
            response.headers["Idempotent-Replayed"] = "true"
        return schema.model_validate(document, from_attributes=True)

    def list_(
        session: SessionDep,
        key: ReadKey,
        limit: Limit = DEFAULT_PAGE,
        cursor: Cursor = None,
        **ids: str,
    ) -> BaseModel:
        items, next_cursor = deployments.list_deployments(
            session, subject, subject_id=ids[id_name], limit=limit, cursor=cursor
        )
        return page(schema, items, next_cursor)

    path = f"{subject.path}/{{{id_name}}}/deployments"
    router.add_api_route(
        path,
        _without_ids(_with_id(deploy, id_name, words.deploy_name, words.deploy)),
        methods=["POST"],
        status_code=201,
        response_model=schema,
        responses={**_FAILURES, **{code: {"description": d} for code, d in words.failures}},
    )
    router.add_api_route(
        path,
        _without_ids(_with_id(list_, id_name, words.list_name, words.list)),
        methods=["GET"],
        response_model=Page[schema],  # type: ignore[valid-type]
    )
    return router


def _without_ids(endpoint: Endpoint) -> Endpoint:
    """The signature FastAPI reads, without the `**ids` the subject's id arrives in."""
    signature: inspect.Signature = endpoint.__signature__  # type: ignore[attr-defined]
    kept = [p for p in signature.parameters.values() if p.kind != p.VAR_KEYWORD]
    endpoint.__signature__ = signature.replace(parameters=kept)  # type: ignore[attr-defined]
    return endpoint


TOOL_WORDS = Words(
    deploy_name="deploy_tool",
    deploy="""Write the tool's active version (and its load) into its robot's controller, read it
    back and compare (within 0.001 mm and 0.001 deg: `verified`, with what the controller
    held before as `previous`). Every attempt is recorded; a failed one answers 502
    `/controller-unreachable`, `/controller-refused` or `/controller-mismatch` with its
    `deployment_id` and `deployment_status`: `not_written` (it failed before the write was sent),
    `unverified` (after: the controller may hold either frame, and the next reconcile round
    records which) or `mismatch`. 409 `/no-active-version`; 422 naming the tool's `slot` or
    `controller_symbol` when the controller cannot address it. The body is `{}` (or none) or
    `{"reason": "..."}`. Calibrate scope; retry-safe with `Idempotency-Key`.""",
    list_name="list_deployments",
    list="""A tool's deployments, newest first: verified, not_written, unverified (with what the
    next reconcile round found, `settled`) or mismatch, each with what the controller held
    before and read back, and the reason given.""",
)

FRAME_WORDS = Words(
    deploy_name="deploy_frame",
    deploy="""Write the frame's active version (a pose in the robot's base frame: a base, or a fixed
    tool) into its robot's controller, read it back and compare (within 0.001 mm and 0.001 deg:
    `verified`, with what the controller held before as `previous`), as a tool's deployment:
    every attempt is recorded; a failed one answers 502 with its `deployment_id` and
    `deployment_status` (not_written, unverified, mismatch). 501 `/no-frame-writer` where no
    remote interface of the controller writes a frame, with its `reason` and
    the `file` to load by hand (nothing is sent). 409 `/no-active-version`; 422 naming the
    frame's `slot` or `controller_symbol` when the controller cannot address it. Calibrate
    scope; retry-safe with `Idempotency-Key`.""",
    failures=(
        (
            501,
            "no remote interface of the controller writes a frame (`/no-frame-writer`): "
            "`reason` says why and `file` names the file to load by hand; nothing was sent",
        ),
    ),
    list_name="list_frame_deployments",
    list="""A frame's deployments, newest first: verified, not_written, unverified (with what the
    next reconcile round found, `settled`) or mismatch, each with what the controller held
    before and read back, and the reason given.""",
)

router = APIRouter()
router.include_router(deployments_router(TOOL, TOOL_WORDS))
router.include_router(deployments_router(FRAME, FRAME_WORDS))
