"""FastAPI dependency aliases: the database session and the authenticated caller."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, Request
from sqlalchemy.orm import Session

from app.auth import Principal, authenticate
from app.db import session_scope
from app.middleware import KEY_NAME

READ_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def get_session(request: Request) -> Iterator[Session]:
    """One transaction per request: committed when the endpoint returns, else rolled back.

    Registered with scope="function" so the commit happens before the response is sent:
    a failed commit can never be answered with 201.
    """
    with session_scope(write=request.method not in READ_METHODS) as session:
        yield session


SessionDep = Annotated[Session, Depends(get_session, scope="function")]


def _principal(scope: str) -> object:
    def dependency(request: Request, session: SessionDep) -> Principal:
        principal = authenticate(session, request.headers.get("authorization"), required=scope)
        request.scope[KEY_NAME] = principal.name  # for the access log line; never the key
        return principal

    dependency.__name__ = f"require_{scope}"
    return Depends(dependency)


ReadKey = Annotated[Principal, _principal("read")]
CalibrateKey = Annotated[Principal, _principal("calibrate")]
AdminKey = Annotated[Principal, _principal("admin")]
