"""The RFC 9457 problem+json document every failure leaves as.

Below the routers and the middleware both: the body-size limit answers 413 with it before
any route is reached, and app.api.problems maps every error to it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from starlette.responses import JSONResponse

from app.config import get_settings

PROBLEM_JSON = "application/problem+json"
ErrorItem = dict[str, object]


def problem_response(
    *,
    status: int,
    kind: str,
    title: str,
    detail: str,
    errors: Sequence[ErrorItem] | None = None,
    headers: Mapping[str, str] | None = None,
    extra: Mapping[str, object] | None = None,
) -> JSONResponse:
    """An RFC 9457 problem document."""
    body: dict[str, object] = {
        "type": get_settings().problem_type(kind),
        "title": title,
        "status": status,
        "detail": detail,
    }
    if errors:
        body["errors"] = list(errors)
    for name, value in (extra or {}).items():
        # RFC 9457's own members keep their meaning: an extension never replaces them (a
        # version's "status" once overwrote the HTTP status with a string).
        body.setdefault(name, value)
    return JSONResponse(body, status_code=status, media_type=PROBLEM_JSON, headers=headers)
