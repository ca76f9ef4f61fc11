"""Domain errors and the one handler that turns every error into RFC 9457 problem+json.

Services raise DomainError subclasses (never HTTPException); the pure libraries raise
SolveError. Both, FastAPI's validation errors and Starlette's 404/405 all leave through
`problem_response`, so a client sees one shape for every failure and never a stack trace.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import IntegrityError
from starlette.exceptions import HTTPException as StarletteHTTPException

from app.config import get_settings
from app.schemas.calibrations import METHOD_NAMES
from app.solvers.errors import SolveError

log = logging.getLogger("tcpcal.errors")

PROBLEM_JSON = "application/problem+json"


class DomainError(Exception):
    """An expected failure of a use case, with its HTTP status and problem type."""

    status: int = 400
    type: str = "bad-request"
    title: str = "Bad request"

    def __init__(
        self,
        detail: str,
        *,
        errors: Sequence[dict[str, Any]] | None = None,
        headers: dict[str, str] | None = None,
        extra: dict[str, Any] | None = None,
    ) -> None:
        super().__init__(detail)
        self.detail = detail
        self.errors = list(errors) if errors else None
        self.headers = headers
        self.extra = extra or {}


class NotFound(DomainError):
    status, type, title = 404, "not-found", "Not found"


class Archived(DomainError):
    status, type, title = 404, "archived", "Archived"


class NoActiveVersion(DomainError):
    status, type, title = 404, "no-active-version", "No active version"


class Conflict(DomainError):
    status, type, title = 409, "conflict", "Conflict"


class IdempotencyConflict(DomainError):
    status, type, title = 409, "idempotency-key-reused", "Idempotency key reused"


class PreconditionFailed(DomainError):
    status, type, title = 412, "precondition-failed", "Precondition failed"


class Unauthorized(DomainError):
    status, type, title = 401, "unauthorized", "Unauthorized"


class Forbidden(DomainError):
    status, type, title = 403, "forbidden", "Forbidden"


class PayloadTooLarge(DomainError):
    status, type, title = 413, "payload-too-large", "Payload too large"


class InvalidInput(DomainError):
    """422 with a specific kind (e.g. "invalid-options") and the field it concerns."""

    status, title = 422, "Invalid input"

    def __init__(self, kind: str, detail: str, *, loc: Sequence[str | int] = ()) -> None:
        super().__init__(detail, errors=[{"loc": list(loc), "msg": detail}] if loc else None)
        self.type = kind


def problem_type(kind: str) -> str:
    """The `type` URI of a problem kind."""
    return f"{get_settings().problem_type_base.rstrip('/')}/{kind}"


def problem_response(
    *,
    status: int,
    kind: str,
    title: str,
    detail: str,
    errors: Sequence[dict[str, Any]] | None = None,
    headers: dict[str, str] | None = None,
    extra: dict[str, Any] | None = None,
) -> JSONResponse:
    """An RFC 9457 problem document."""
    body: dict[str, Any] = {
        "type": problem_type(kind),
        "title": title,
        "status": status,
        "detail": detail,
    }
    if errors:
        body["errors"] = list(errors)
    if extra:
        body.update(extra)
    return JSONResponse(body, status_code=status, media_type=PROBLEM_JSON, headers=headers)


def solve_error_response(exc: SolveError) -> JSONResponse:
    """422 for input a library could not use."""
    errors = [{"loc": list(exc.loc), "msg": exc.detail}] if exc.loc else None
    return problem_response(
        status=422,
        kind=exc.kind,
        title=exc.title,
        detail=exc.detail,
        errors=errors,
        extra={"context": exc.extra} if exc.extra else None,
    )


def _loc(loc: Sequence[Any]) -> list[str | int]:
    """A field path without pydantic's union-member tags ("manual", "list[float]", ...)."""
    path: list[str | int] = []
    for i, part in enumerate(loc):
        if isinstance(part, str):
            is_member_tag = "[" in part or part[:1].isupper() or part.startswith("function-")
            is_discriminator = i == 1 and loc[0] == "body" and part in METHOD_NAMES
            if is_member_tag or is_discriminator:
                continue
        path.append(part)
    return path


def validation_response(exc: RequestValidationError) -> JSONResponse:
    """422 naming every offending field; NaN/Infinity get the /non-finite type."""
    errors = []
    non_finite = False
    for err in exc.errors():
        if err.get("type") == "finite_number":
            non_finite = True
        loc = _loc(err.get("loc", ()))
        if err.get("type") in {"union_tag_invalid", "union_tag_not_found"}:
            # pydantic reports a bad discriminator at its parent; name the field itself
            loc.append(str(err.get("ctx", {}).get("discriminator", "")).strip("'"))
        errors.append({"loc": loc, "msg": str(err.get("msg", ""))})
    first = errors[0] if errors else {"loc": [], "msg": "invalid request"}
    where = ".".join(str(p) for p in first["loc"]) or "body"
    detail = f"{where}: {first['msg']}"
    if len(errors) > 1:
        detail += f" (and {len(errors) - 1} more)"
    if non_finite:
        return problem_response(
            status=422, kind="non-finite", title="Non-finite value", detail=detail, errors=errors
        )
    return problem_response(
        status=422, kind="validation", title="Invalid request", detail=detail, errors=errors
    )


#: Unique constraints a concurrent request can lose against, and the field each guards.
#: The services check first and name the field; this covers the race between check and insert
#: (SQLite serialises writers, PostgreSQL lets both checks pass).
UNIQUE_FIELDS = {
    "uq_robots_live_name": "name",
    "uq_tools_live_name": "name",
    "uq_tools_live_slot": "slot",
    "uq_reference_points_robot_name": "name",
    "uq_laser_devices_robot_name": "name",
}
IDEMPOTENCY_CONSTRAINT = "uq_idempotency_records_key"


def _violated_constraint(exc: IntegrityError) -> str | None:
    diag = getattr(exc.orig, "diag", None)
    name = getattr(diag, "constraint_name", None)
    if name:
        return str(name)
    text = str(exc.orig)
    return next((n for n in (*UNIQUE_FIELDS, IDEMPOTENCY_CONSTRAINT) if n in text), None)


def integrity_response(exc: IntegrityError) -> JSONResponse:
    """409 for a unique constraint lost to a concurrent request; anything else is a bug."""
    name = _violated_constraint(exc)
    if name == IDEMPOTENCY_CONSTRAINT:
        return problem_response(
            status=409,
            kind=IdempotencyConflict.type,
            title=IdempotencyConflict.title,
            detail="this Idempotency-Key was just used by another request; use a new key for a "
            "new submission",
        )
    if name in UNIQUE_FIELDS:
        field = UNIQUE_FIELDS[name]
        return problem_response(
            status=409,
            kind=Conflict.type,
            title=Conflict.title,
            detail=f"{field} is already taken (by a request that arrived at the same time)",
            errors=[{"loc": ["body", field], "msg": "already taken"}],
        )
    log.error("integrity error outside the known unique constraints: %s", exc.orig)
    return problem_response(
        status=500,
        kind="internal-error",
        title="Internal server error",
        detail="the server failed to handle this request; it has been logged",
    )


def install_error_handlers(app: FastAPI) -> None:
    """Route every error the app can produce through problem_response."""

    @app.exception_handler(DomainError)
    async def _domain(_: Request, exc: DomainError) -> JSONResponse:
        return problem_response(
            status=exc.status,
            kind=exc.type,
            title=exc.title,
            detail=exc.detail,
            errors=exc.errors,
            headers=exc.headers,
            extra=exc.extra,
        )

    @app.exception_handler(SolveError)
    async def _solve(_: Request, exc: SolveError) -> JSONResponse:
        return solve_error_response(exc)

    @app.exception_handler(IntegrityError)
    async def _integrity(_: Request, exc: IntegrityError) -> JSONResponse:
        return integrity_response(exc)

    @app.exception_handler(RequestValidationError)
    async def _validation(_: Request, exc: RequestValidationError) -> JSONResponse:
        return validation_response(exc)

    @app.exception_handler(StarletteHTTPException)
    async def _http(_: Request, exc: StarletteHTTPException) -> JSONResponse:
        if exc.status_code == 400:
            # Starlette's "error parsing the body" (not UTF-8, not JSON): malformed input,
            # which the contract answers with 422 like every other malformed body
            return problem_response(
                status=422,
                kind="validation",
                title="Invalid request",
                detail=f"body: {exc.detail}; send UTF-8 JSON",
                errors=[{"loc": ["body"], "msg": str(exc.detail)}],
            )
        kinds = {404: ("not-found", "Not found"), 405: ("method-not-allowed", "Method not allowed")}
        kind, title = kinds.get(exc.status_code, ("http-error", "HTTP error"))
        return problem_response(
            status=exc.status_code,
            kind=kind,
            title=title,
            detail=str(exc.detail),
            headers=getattr(exc, "headers", None),
        )

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        # A bug, not bad input: log the cause, answer without internals.
        log.exception("unhandled error on %s %s", request.method, request.url.path)
        return problem_response(
            status=500,
            kind="internal-error",
            title="Internal server error",
            detail="the server failed to handle this request; it has been logged",
        )
