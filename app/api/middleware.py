"""ASGI middleware: body-size limit (keeping the raw body); request id, access line, metrics."""

from __future__ import annotations

import logging
import re
import time
from uuid import uuid4

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.api.problem_json import problem_response
from app.logs import KEY_NAME, REQUEST_ID, access_logger
from app.metrics import REQUEST_SECONDS, REQUESTS

BODY_METHODS = frozenset({"POST", "PUT", "PATCH"})


class BodyLimitMiddleware:
    """Refuse bodies over the limit with 413 before any parsing.

    Content-Length is checked first; chunked bodies are counted as they arrive, so a client
    cannot get past the limit by omitting the header.
    """

    def __init__(self, app: ASGIApp, *, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def _too_large(self, scope: Scope, receive: Receive, send: Send) -> None:
        response = problem_response(
            status=413,
            kind="payload-too-large",
            title="Payload too large",
            detail=f"request body exceeds {self.max_bytes} bytes "
            f"({self.max_bytes // 1024} KiB); split the submission",
        )
        await response(scope, receive, send)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] not in BODY_METHODS:
            await self.app(scope, receive, send)
            return
        for name, value in scope["headers"]:
            if name == b"content-length":
                try:
                    declared = int(value)
                except ValueError:
                    declared = 0
                if declared > self.max_bytes:
                    await self._too_large(scope, receive, send)
                    return
        chunks: list[bytes] = []
        size = 0
        more = True
        while more:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_bytes:
                await self._too_large(scope, receive, send)
                return
            chunks.append(chunk)
            more = message.get("more_body", False)
        body = b"".join(chunks)
        sent = False

        async def replay() -> Message:
            nonlocal sent
            if not sent:
                sent = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


class HeadAsGetMiddleware:
    """Answer HEAD wherever GET is answered, with GET's status and headers and no body, as
    HTTP requires of every GET resource (RFC 9110 9.3.2): monitors and load balancers probe
    /health and /ui/ with HEAD, and FastAPI's routes answer only the methods they declare.
    The access line still says HEAD, with the route and key the GET found."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "HEAD":
            await self.app(scope, receive, send)
            return

        async def no_body(message: Message) -> None:
            if message["type"] == "http.response.body":
                message = {**message, "body": b""}
            await send(message)

        # The same scope, so the router's route and the key's name reach the access line.
        scope["method"] = "GET"
        try:
            await self.app(scope, receive, no_body)
        finally:
            scope["method"] = "HEAD"


#: Request ids accepted from clients: what a tracing header holds, nothing that could
#: break a log line. Anything else is replaced by a generated id.
_REQUEST_ID = re.compile(r"[A-Za-z0-9._:-]{1,128}")
_log = logging.getLogger("tcpcal")


def valid_request_id(value: str) -> bool:
    return _REQUEST_ID.fullmatch(value) is not None


def request_id(scope: Scope) -> str:
    """The client's X-Request-ID when it is a valid one, else a new id (32 hex digits)."""
    for name, value in scope["headers"]:
        if name == b"x-request-id":
            sent: str = value.decode("latin-1")
            if valid_request_id(sent):
                return sent
            made = uuid4().hex
            # Not the value itself: it is what could break or forge a log line.
            _log.warning("X-Request-ID refused (1-128 of A-Za-z0-9._:- expected); using %s", made)
            return made
    return uuid4().hex


class RequestLogMiddleware:
    """Per request: its id (the client's X-Request-ID or a new one, in REQUEST_ID for every
    log line and echoed in the response), one access log line and the request metrics, by
    route template (not the raw path, so ids do not explode the labels), with the name of
    the key that was used. One layer for all three: asgi-correlation-id's middleware, a layer
    of its own, cost 9% of the hot read (bench/wrk_load.py)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        status = 500
        rid = request_id(scope)
        REQUEST_ID.set(rid)  # the request's own task (and the threads it hands work to)
        echo = (b"x-request-id", rid.encode("latin-1"))

        async def send_wrapper(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
                message = {**message, "headers": [*message.get("headers", ()), echo]}
            await send(message)

        try:
            await self.app(scope, receive, send_wrapper)
        finally:
            seconds = time.perf_counter() - start
            template = getattr(scope.get("route"), "path", None) or "unmatched"
            method = scope["method"]
            REQUESTS.labels(method, template, str(status)).inc()
            REQUEST_SECONDS.labels(method, template).observe(seconds)
            access_logger().info(
                "request",
                method=method,
                route=template,
                path=scope["path"],
                status=status,
                duration_ms=round(1000.0 * seconds, 3),
                key=scope.get(KEY_NAME),
            )
