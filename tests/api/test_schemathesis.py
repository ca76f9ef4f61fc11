"""Property-based fuzzing of every operation against the app's own OpenAPI schema (schemathesis).

Each operation gets a freshly seeded database (a robot, a tool with an active version, a
reference point) and up to MAX_EXAMPLES generated requests, valid and invalid, sent with an
admin key; path parameters hit the seeded ids about half the time. Checked for every
response: never a 5xx; success responses match the documented status, content type, headers
and body schema; every 4xx is an RFC 9457 problem+json with type, title, status and detail.
"""

from __future__ import annotations

from typing import Any

import hypothesis.strategies as st
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from app.main import create_app
from tests.conftest import Api

MAX_EXAMPLES = 25
PROBLEM_JSON = "application/problem+json"

schema = schemathesis.openapi.from_dict(
    create_app().openapi(),
    config=schemathesis.Config.from_dict(
        {
            "generation": {"mode": "all", "max-examples": MAX_EXAMPLES, "deterministic": True},
            "phases": {
                "examples": {"enabled": False},
                "coverage": {"enabled": False},
                "stateful": {"enabled": False},
            },
        }
    ),
)

FUZZ_SETTINGS = settings(
    max_examples=MAX_EXAMPLES,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=list(HealthCheck),
)


def _seed(api: Api) -> dict[str, Any]:
    """A robot, a tool with version 1 active, a reference point; their ids by path parameter."""
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


def problem_details(ctx: Any, response: schemathesis.Response, case: schemathesis.Case) -> None:
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
ERROR_CHECKS = [not_a_server_error, problem_details]


@schema.parametrize()
@schema.given(data=st.data())
@FUZZ_SETTINGS
def test_api_conforms_to_its_schema(case: schemathesis.Case, data: st.DataObject, api: Api) -> None:
    """No 5xx; 2xx/3xx as documented; 4xx as problem details."""
    seeded = _seeded_ids(api)
    for name in case.path_parameters or {}:
        if name in seeded and data.draw(st.booleans(), label=f"real {name}"):
            case.path_parameters[name] = seeded[name]
    response = case.call(app=api.client.app, headers=api.headers("admin"))
    checks = SUCCESS_CHECKS if response.status_code < 400 else ERROR_CHECKS
    case.validate_response(response, checks=checks)


_SEEDED: dict[int, dict[str, Any]] = {}


def _seeded_ids(api: Api) -> dict[str, Any]:
    """Seed once per test (one `api` fixture per operation)."""
    if id(api) not in _SEEDED:
        _SEEDED.clear()
        _SEEDED[id(api)] = _seed(api)
    return _SEEDED[id(api)]
