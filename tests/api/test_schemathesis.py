"""Property-based fuzzing of every operation against the app's own OpenAPI schema (schemathesis),
read from openapi/openapi.json, which tests/test_openapi.py holds equal to the app's, byte for
byte (building the app's schema at collection cost every pytest worker a second of CPU).

Each operation gets a freshly seeded database (a robot, a tool with an active version, a
reference point) and up to MAX_EXAMPLES generated requests, valid and invalid, sent with an
admin key; path parameters often hit the seeded ids, integer ones also the database integer
limits. Checked for every response: never a 5xx; success responses match the documented
status, content type, headers and body schema; every 4xx is an RFC 9457 problem+json with
type, title, status and detail.
Errors are checked against the spec too (it documents them as problem+json).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import hypothesis.strategies as st
import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, settings
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from tests.conftest import Api

MAX_EXAMPLES = 20
SEED = 20240611
PROBLEM_JSON = "application/problem+json"
HUGE_VERSION = 2**63  # one past SQLite's INTEGER
INT32_VERSION = 2**31  # one past PostgreSQL's integer
#: integer path parameters also try the edges of the database integer types
DATABASE_INT_EDGES = [INT32_VERSION, HUGE_VERSION, -(2**63) - 1]

SPEC = Path(__file__).resolve().parents[2] / "openapi" / "openapi.json"

schema = schemathesis.openapi.from_path(
    SPEC,
    config=schemathesis.Config.from_dict(
        {
            # a fixed seed, derived per operation: editing this file does not change the cases
            "seed": SEED,
            "generation": {"mode": "all", "max-examples": MAX_EXAMPLES},
            "phases": {
                "examples": {"enabled": False},
                "coverage": {"enabled": False},
                "stateful": {"enabled": False},
            },
        }
    ),
)


def _seed(api: Api) -> dict[str, Any]:
    """A robot, a tool with version 1 active, a reference point: their ids by path parameter."""
    robot = api.robot("fuzz-robot", vendor="KUKA")
    tool = api.tool(robot["id"], "fuzz-tool", slot=3)
    calibration = api.manual(tool["id"], [0.0, 0.0, 150.0])
    point = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "fuzz-point", "position_mm": [500.0, 0.0, 200.0]},
        scope="calibrate",
    )
    assert point.status_code == 201, point.text
    keys = api.get("/v1/keys", scope="admin").json()["items"]
    read_key = next(key for key in keys if key["name"] == "test-read")
    return {
        "robot_id": robot["id"],
        "tool_id": tool["id"],
        "calibration_id": calibration["id"],
        "point_id": point.json()["id"],
        "key_id": read_key["id"],
        "version": 1,
    }


@pytest.fixture
def seeded_ids(api: Api) -> dict[str, Any]:
    """Ids of the seeded rows, by the path parameter that names them: seeded once per backend,
    and the database put back as seeded before each operation's examples (Api.world)."""
    return api.world(_seed)


class ResponseOnly:
    """An ASGI app that answers like the wrapped one but never re-raises after its 500.

    Starlette sends the 500 and then re-raises for the server's log; schemathesis' in-process
    client would turn that into an exception instead of a response to check.
    """

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        """Forward the request; swallow an error raised after the response started."""
        started = False

        async def tracking_send(message: Any) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, receive, tracking_send)
        except Exception:
            if not started:
                raise


def problem_details(
    ctx: Any, response: schemathesis.Response, case: schemathesis.Case[Any]
) -> None:
    """Every 4xx is application/problem+json carrying type, title, status and detail."""
    if not 400 <= response.status_code < 500:
        return
    content_type = response.headers.get("content-type", [""])[0]
    assert content_type.startswith(PROBLEM_JSON), f"4xx with content-type {content_type!r}"
    body = response.json()
    assert isinstance(body, dict), f"problem body is not an object: {body!r}"
    missing = {"type", "title", "status", "detail"} - body.keys()
    assert not missing, f"problem lacks {sorted(missing)}: {body!r}"
    assert body["status"] == response.status_code, f"status {body['status']} in the body"


SUCCESS_CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
]
ERROR_CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_schema_conformance,
    problem_details,
]


@schema.parametrize()
@schema.given(data=st.data())
@settings(
    max_examples=MAX_EXAMPLES,
    deadline=None,
    database=None,
    phases=[Phase.explicit, Phase.generate, Phase.shrink],
    suppress_health_check=list(HealthCheck),
)
def test_api_conforms_to_its_schema(
    case: schemathesis.Case[Any],
    data: st.DataObject,
    api: Api,
    seeded_ids: dict[str, Any],
) -> None:
    """No 5xx; 2xx/3xx as documented; 4xx as problem details."""
    for name, generated in (case.path_parameters or {}).items():
        choices = [generated]
        if name in seeded_ids:
            choices.append(seeded_ids[name])
        if isinstance(generated, int):
            choices.extend(DATABASE_INT_EDGES)
        case.path_parameters[name] = data.draw(st.sampled_from(choices), label=name)
    response = case.call(app=ResponseOnly(api.client.app), headers=api.headers("admin"))
    checks = SUCCESS_CHECKS if response.status_code < 400 else ERROR_CHECKS
    case.validate_response(response, checks=checks)


@pytest.mark.parametrize("version", [HUGE_VERSION, INT32_VERSION])
@pytest.mark.parametrize("method", ["GET", "POST"])
def test_out_of_range_version_is_422(
    api: Api, seeded_ids: dict[str, Any], method: str, version: int
) -> None:
    """Regression: versions beyond the database integers reached the query (500)."""
    path = f"/v1/tools/{seeded_ids['tool_id']}/versions/{version}"
    if method == "POST":
        response = api.post(f"{path}/activate", scope="calibrate")
    else:
        response = api.get(path)
    assert response.status_code == 422, response.text
    assert response.json()["errors"][0]["loc"] == ["path", "version"]


def test_documented_422_matches_what_is_sent(api: Api) -> None:
    """Regression: the spec documented FastAPI's HTTPValidationError, not problem+json."""
    case = schema["/v1/robots"]["POST"].Case(body={})
    response = case.call(app=ResponseOnly(api.client.app), headers=api.headers("admin"))
    assert response.status_code == 422
    case.validate_response(response, checks=[content_type_conformance, response_schema_conformance])
