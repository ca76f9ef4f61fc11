"""The CLI's one way to the server: the HTTP client built from TCPCAL_URL and TCPCAL_API_KEY,
what an unreachable server or a refused request prints, and the exit codes they end in.

Every client command (app.cli.client, app.cli.controllers, `tcpcal client get|post`) sends
through `request` or `send`; tests point `connect` at the app in process.

httpx is imported by the functions that send (it brings its own CLI's click, rich and pygments
when imported: about 0.1 s of CPU): every tcpcal process imports this module with app.cli, the
server's workers and solver processes too, and only a client command sends.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, NoReturn

import typer
from rich.console import Console

from app.jsontypes import JsonArray, JsonObject

if TYPE_CHECKING:
    import httpx

EXIT_BAD_USE = 2
EXIT_OUT_OF_TOLERANCE = 3
EXIT_REFUSED = 4
EXIT_NOT_FOUND = 5
EXIT_UNREACHABLE = 6

DEFAULT_URL = "http://127.0.0.1:8000"
#: A calibration is solved while the request waits: long enough for the slowest method.
TIMEOUT_S = 120

Params = Mapping[str, str | int]

out = Console()
err = Console(stderr=True)


def fail(code: int, message: str) -> NoReturn:
    """Print `message` as an error and exit with `code`."""
    err.print(f"[bold red]error[/]: {message}", highlight=False)
    raise typer.Exit(code)


def server_url() -> str:
    """The server the client talks to (TCPCAL_URL)."""
    return os.environ.get("TCPCAL_URL", DEFAULT_URL)


def connect() -> httpx.Client:
    """An HTTP client for the configured server with the configured key (exit 2 without)."""
    import httpx

    key = os.environ.get("TCPCAL_API_KEY")
    if not key:
        fail(EXIT_BAD_USE, f"set TCPCAL_API_KEY (and TCPCAL_URL if not {DEFAULT_URL})")
    return httpx.Client(
        base_url=server_url(), headers={"Authorization": f"Bearer {key}"}, timeout=TIMEOUT_S
    )


def request(
    method: str,
    path: str,
    *,
    params: Params | None = None,
    json: JsonObject | JsonArray | None = None,
    headers: Mapping[str, str] | None = None,
) -> httpx.Response:
    """The server's answer whatever its status; exit 6 when the server cannot be reached."""
    import httpx

    try:
        with connect() as http:
            return http.request(method, path, params=params, json=json, headers=headers)
    except httpx.HTTPError as exc:
        fail(EXIT_UNREACHABLE, f"could not reach {server_url()}: {exc}")


def send(
    method: str,
    path: str,
    *,
    params: Params | None = None,
    json: JsonObject | JsonArray | None = None,
    headers: Mapping[str, str] | None = None,
) -> httpx.Response:
    """The server's answer to a request that must succeed: a 4xx or 5xx exits (`refused`)."""
    response = request(method, path, params=params, json=json, headers=headers)
    if response.status_code >= 400:
        refused(response)
    return response


def problem(response: httpx.Response) -> JsonObject:
    """The problem document of a failed answer ({"detail": its text} when it is not one)."""
    try:
        body = response.json()
    except ValueError:
        return {"detail": response.text}
    return body if isinstance(body, dict) else {"detail": response.text}


def refused(response: httpx.Response) -> NoReturn:
    """Exit saying what the server refused: 5 for 401/403/404, 6 for 5xx, 4 otherwise."""
    body = problem(response)
    detail = str(body.get("detail") or response.reason_phrase)
    if "suggestion" in body:
        detail += f"\nsuggestion: {json.dumps(body['suggestion'])}"
    code = response.status_code
    if code in (401, 403, 404):
        fail(EXIT_NOT_FOUND, f"{code}: {detail}")
    if code >= 500:
        fail(EXIT_UNREACHABLE, f"{code}: {detail}")
    fail(EXIT_REFUSED, f"{code}: {detail}")
