"""An httpx transport that sends each request to an entered TestClient's app in one call to
its event loop thread.

Starlette's own transport crosses from the test's thread to the loop's and back about nine
times a request (two events, a memory stream, a cancel scope, the app's task, the wait for
the response, one crossing per body chunk and one for its end, the close), each a wake-up
of the other thread: under load on 2 cores (`make test`) that was 4-6 ms of a 10-16 ms
GET /v1/robots, measured beside one crossing a request. Here the whole exchange runs in
one coroutine on the same loop, with the app, scope, lifespan state and
raise_server_exceptions=False answers of the TestClient: the response as the app sent it
(a 500 from the server-error handler included), or an empty 500 when the app raised or
returned before answering. The request body is sent in one message; after it, `receive` waits for
the response to end and then reports the disconnect, as the TestClient's does.
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote

import anyio
import httpx

if TYPE_CHECKING:
    from fastapi.testclient import TestClient

#: The ports the TestClient gives a URL without one.
DEFAULT_PORTS = {"http": 80, "https": 443}
#: What the TestClient gives as the client's address.
CLIENT = ("testclient", 50000)

Message = dict[str, Any]


class InProcessTransport(httpx.BaseTransport):
    """Requests to the app of `client` (a TestClient inside its `with`: lifespan started)."""

    def __init__(self, client: TestClient) -> None:
        self._client = client

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        portal = self._client.portal
        assert portal is not None, "the TestClient is not entered"
        scope = _scope(request, self._client.app_state)
        status, headers, body = portal.call(_exchange, self._client.app, scope, request.read())
        return httpx.Response(
            status,
            headers=[(k.decode(), v.decode()) for k, v in headers],
            stream=httpx.ByteStream(body),
            request=request,
        )


def _scope(request: httpx.Request, app_state: dict[str, Any]) -> dict[str, Any]:
    """The ASGI scope the TestClient builds for an HTTP request."""
    url = request.url
    headers = [] if "host" in request.headers else [(b"host", url.netloc)]
    headers += [(k.lower().encode(), v.encode()) for k, v in request.headers.multi_items()]
    host = url.raw_host.decode("ascii")
    return {
        "type": "http",
        "http_version": "1.1",
        "method": request.method,
        "path": unquote(url.path),
        "raw_path": url.raw_path.split(b"?", 1)[0],
        "root_path": "",
        "scheme": url.scheme,
        "query_string": url.query,
        "headers": headers,
        "client": CLIENT,
        "server": [host, url.port or DEFAULT_PORTS[url.scheme]],
        "extensions": {"http.response.debug": {}, "http.response.trailers": {}},
        "state": app_state.copy(),
    }


async def _exchange(
    app: Any, scope: dict[str, Any], body: bytes
) -> tuple[int, list[tuple[bytes, bytes]], bytes]:
    """Run the app for one request: (status, headers, body) as it answered."""
    start: Message = {}
    chunks: list[bytes] = []
    ended = anyio.Event()
    asked = False

    async def receive() -> Message:
        nonlocal asked
        if not asked:
            asked = True
            return {"type": "http.request", "body": body}
        await ended.wait()
        return {"type": "http.disconnect"}

    async def send(message: Message) -> None:
        if message["type"] == "http.response.start":
            assert not start, "two http.response.start messages"
            start.update(message)
        elif message["type"] == "http.response.body":
            assert start, "http.response.body before http.response.start"
            chunks.append(bytes(message.get("body", b"")))
            if not message.get("more_body", False):
                ended.set()

    # An error raised after answering is the server-error handler's, re-raised for the log
    # after its 500 was sent: the answer stands.
    with contextlib.suppress(Exception):
        await app(scope, receive, send)
    ended.set()
    if not start:  # raised or returned before answering: the TestClient's empty 500
        return 500, [], b""
    return int(start["status"]), list(start.get("headers", [])), b"".join(chunks)
