"""The HTTP face of errors: every failure leaves as one RFC 9457 problem+json document.

Domain errors (app.errors), FastAPI's validation errors, lost unique-constraint races and
Starlette's 404/405 are all answered through `problem_response`, so a client sees one shape
for every failure and never a stack trace.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import IntegrityError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match

from app.api.problem_json import ErrorItem, problem_response
from app.errors import INPUT_KINDS, Conflict, DomainError, IdempotencyConflict
from app.methods import METHOD_NAMES

log = logging.getLogger("tcpcal.errors")


def domain_error_response(exc: DomainError) -> JSONResponse:
    """The problem document of a domain error; its loc names the field in `errors`."""
    errors: list[ErrorItem] | None = [{"loc": list(exc.loc), "msg": exc.msg}] if exc.loc else None
    extra: dict[str, object] = dict(exc.members)
    if exc.context:
        extra["context"] = exc.context
    return problem_response(
        status=exc.status,
        kind=exc.kind,
        title=exc.title,
        detail=exc.detail,
        errors=errors,
        headers=exc.headers or None,
        extra=extra or None,
    )


def internal_error_response() -> JSONResponse:
    """500: a bug, not bad input; the cause is logged, never sent."""
    return problem_response(
        status=500,
        kind="internal-error",
        title="Internal server error",
        detail="the server failed to handle this request; it has been logged",
    )


def _loc(loc: Sequence[str | int]) -> list[str | int]:
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


def validation_response(
    exc: RequestValidationError, content_type: str | None = None
) -> JSONResponse:
    """422 naming every offending field; the kind is the most specific one known. A body
    refused as a whole that was not sent as JSON (curl -d without a Content-Type header sends a
    form) says which header to send."""
    errors: list[ErrorItem] = []
    kinds: list[str] = []
    for err in exc.errors():
        err_type = str(err.get("type", ""))
        if err_type == "finite_number":
            kinds.append("non-finite")
        elif err_type in INPUT_KINDS:  # a schema's own check (PydanticCustomError)
            kinds.append(err_type)
        loc = _loc(err.get("loc", ()))
        if err_type in {"union_tag_invalid", "union_tag_not_found"}:
            # pydantic reports a bad discriminator at its parent; name the field itself
            loc.append(str(err.get("ctx", {}).get("discriminator", "")).strip("'"))
        errors.append({"loc": loc, "msg": str(err.get("msg", ""))})
    first = errors[0] if errors else {"loc": [], "msg": "invalid request"}
    where = ".".join(str(p) for p in first["loc"]) or "body"  # type: ignore[attr-defined]
    detail = f"{where}: {first['msg']}"
    if len(errors) > 1:
        detail += f" (and {len(errors) - 1} more)"
    if first["loc"] == ["body"] and "json" not in (content_type or "").lower():
        detail += f"; the body was sent as {content_type or 'no Content-Type'}: send JSON with "
        detail += "the header Content-Type: application/json"
    kind = kinds[0] if kinds else "validation"
    return problem_response(
        status=422, kind=kind, title=INPUT_KINDS[kind], detail=detail, errors=errors
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
        return domain_error_response(
            IdempotencyConflict(
                "this Idempotency-Key was just used by another request; use a new key for a "
                "new submission"
            )
        )
    if name in UNIQUE_FIELDS:
        field = UNIQUE_FIELDS[name]
        return domain_error_response(
            Conflict(
                f"{field} is already taken (by a request that arrived at the same time)",
                loc=("body", field),
                msg="already taken",
            )
        )
    log.error("integrity error outside the known unique constraints: %s", exc.orig)
    return internal_error_response()


_METHODS = ("DELETE", "GET", "HEAD", "OPTIONS", "PATCH", "POST", "PUT")


def _allowed_methods(request: Request) -> list[str]:
    """Every method some route of the app serves at the request's path, asked of the routes
    themselves (Starlette's matching), so that nested routers are covered too. HEAD wherever
    GET is (app.api.middleware.HeadAsGetMiddleware answers it)."""
    allowed = {
        method
        for method in _METHODS
        if any(
            route.matches({**request.scope, "method": method})[0] == Match.FULL
            for route in request.app.router.routes
        )
    }
    if "GET" in allowed:
        allowed.add("HEAD")
    return sorted(allowed)


def install_error_handlers(app: FastAPI) -> None:
    """Route every error the app can produce through problem_response."""

    @app.exception_handler(DomainError)
    async def _domain(_: Request, exc: DomainError) -> JSONResponse:
        return domain_error_response(exc)

    @app.exception_handler(IntegrityError)
    async def _integrity(_: Request, exc: IntegrityError) -> JSONResponse:
        return integrity_response(exc)

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError) -> JSONResponse:
        return validation_response(exc, request.headers.get("content-type"))

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        if exc.status_code == 400:
            # Starlette's "error parsing the body" (not UTF-8, not JSON): malformed input,
            # which the contract answers with 422 like every other malformed body
            return problem_response(
                status=422,
                kind="validation",
                title=INPUT_KINDS["validation"],
                detail=f"body: {exc.detail}; send UTF-8 JSON",
                errors=[{"loc": ["body"], "msg": str(exc.detail)}],
            )
        kinds = {404: ("not-found", "Not found"), 405: ("method-not-allowed", "Method not allowed")}
        kind, title = kinds.get(exc.status_code, ("http-error", "HTTP error"))
        headers = dict(getattr(exc, "headers", None) or {})
        detail = str(exc.detail)
        if exc.status_code == 405:
            # Starlette names only the first route that matched the path; a path may have
            # several (GET and POST /v1/robots are two routes): list every method it has.
            allowed = _allowed_methods(request)
            headers["Allow"] = ", ".join(allowed)
            detail = f"{request.method} is not allowed here; this path allows {', '.join(allowed)}"
        return problem_response(
            status=exc.status_code, kind=kind, title=title, detail=detail, headers=headers or None
        )

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        # A bug, not bad input: log the cause, answer without internals.
        log.exception("unhandled error on %s %s", request.method, request.url.path)
        return internal_error_response()
