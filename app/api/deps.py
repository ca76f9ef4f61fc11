"""FastAPI dependency aliases: the database session and the authenticated caller.

Every route learns who calls through one dependency here (`_principal`), which also names
the key in the request's access log line; the hot read, whose key check is part of its one
statement, names it through `label_request` as well.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Annotated, ParamSpec, TypeVar

from fastapi import Depends, Request
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool

from app.logs import KEY_NAME
from app.scopes import Scope
from app.security.auth import Principal, authenticate, authenticate_held
from app.storage.db import loop_engine, session_scope

READ_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

P = ParamSpec("P")
T = TypeVar("T")


def get_session(request: Request) -> Iterator[Session]:
    """One transaction per request: committed when the endpoint returns, else rolled back.

    Registered with scope="function" so the commit happens before the response is sent:
    a failed commit can never be answered with 201.
    """
    with session_scope(write=request.method not in READ_METHODS) as session:
        yield session


SessionDep = Annotated[Session, Depends(get_session, scope="function")]


async def run_blocking(service: Callable[P, T], /, *args: P.args, **kwargs: P.kwargs) -> T:
    """The one way a route reaches a use case that blocks on a controller (a capture, a
    deployment, a reconcile, a re-check): run in the thread pool, so the event loop keeps
    serving, the use case opening each of its transactions for the caller
    (app.security.auth.transaction_for) and holding none while it waits on the controller.
    Every other route's use case takes the request's session (SessionDep), committed when
    the route returns and limited to the caller's cells as it is authenticated."""
    return await run_in_threadpool(service, *args, **kwargs)


def label_request(request: Request, principal: Principal) -> Principal:
    """Name the caller's key in the request's access log line (its name, never the key)."""
    request.scope[KEY_NAME] = principal.name
    return principal


def _principal(scope: Scope) -> object:
    """The caller, authenticated with the request's session, which is then limited to the
    caller's cells (app.security.auth.act_for)."""

    def dependency(request: Request, session: SessionDep) -> Principal:
        authorization = request.headers.get("authorization")
        return label_request(request, authenticate(session, authorization, required=scope))

    dependency.__name__ = f"require_{scope}"
    return Depends(dependency)


def _held_principal(scope: Scope) -> object:
    """The caller of a route that opens no session for it (a solve, a deployment, a
    reconcile): the key read on the event loop's held connection (app.storage.db.loop_engine).
    A missing, unknown or too narrow key is refused (401, 403) before the body is read, as
    on every other route: an anonymous caller learns nothing of the request's schema."""

    async def dependency(request: Request) -> Principal:
        # On the event loop (async): the held connection is the loop thread's own.
        authorization = request.headers.get("authorization")
        principal = authenticate_held(loop_engine(), authorization, required=scope)
        return label_request(request, principal)

    dependency.__name__ = f"require_{scope}_held"
    return Depends(dependency)


ReadKey = Annotated[Principal, _principal("read")]
CalibrateKey = Annotated[Principal, _principal("calibrate")]
AdminKey = Annotated[Principal, _principal("admin")]
HeldReadKey = Annotated[Principal, _held_principal("read")]
HeldCalibrateKey = Annotated[Principal, _held_principal("calibrate")]
