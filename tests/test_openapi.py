"""The committed openapi/openapi.json is the app's schema (run `tcpcal openapi` to refresh)."""

from __future__ import annotations

import json
from pathlib import Path

from app.api.openapi import openapi_text
from app.main import create_app

SPEC = Path(__file__).resolve().parents[1] / "openapi" / "openapi.json"


def test_committed_spec_is_the_apps_byte_for_byte() -> None:
    """What `tcpcal openapi --check` checks (make check and make test run it as this test)."""
    assert SPEC.read_text() == openapi_text(create_app()), (
        "openapi/openapi.json is stale: run tcpcal openapi"
    )


def test_spec_has_the_contract_paths() -> None:
    paths = json.loads(SPEC.read_text())["paths"]
    for path in (
        "/v1/robots",
        "/v1/robots/{robot_id}",
        "/v1/robots/{robot_id}/tools",
        "/v1/tools/{tool_id}",
        "/v1/tools/{tool_id}/calibrations",
        "/v1/calibrations/{calibration_id}",
        "/v1/tools/{tool_id}/versions",
        "/v1/tools/{tool_id}/versions/{version}/activate",
        "/v1/tools/{tool_id}/rollback",
        "/v1/tools/{tool_id}/tcp",
        "/v1/robots/{robot_id}/tool-table",
        "/v1/keys",
        "/v1/solve",
        "/health",
        "/ready",
        "/metrics",
    ):
        assert path in paths, path


def test_every_operation_and_every_field_is_described() -> None:
    from app.main import create_app

    spec = create_app().openapi()
    undescribed_ops = [
        f"{verb.upper()} {path}"
        for path, item in spec["paths"].items()
        for verb, operation in item.items()
        if not operation.get("description")
    ]
    undescribed_fields = [
        f"{model}.{field}"
        for model, schema in spec["components"]["schemas"].items()
        for field, prop in schema.get("properties", {}).items()
        if not prop.get("description")
    ]
    assert undescribed_ops == []
    assert undescribed_fields == []


def test_every_error_response_is_a_problem_and_keeps_its_routes_words() -> None:
    """Each 4xx/5xx response names the Problem schema; a status a route described itself
    (activate's 409 is /out-of-tolerance, rollback's /nothing-to-roll-back) keeps that text
    instead of the generic one."""
    paths = json.loads(SPEC.read_text())["paths"]
    for path, item in paths.items():
        if path in {"/health", "/ready"}:
            continue  # the probes: /ready's 503 is its readiness document, not a problem
        for method, operation in item.items():
            for code, response in operation["responses"].items():
                if int(code) >= 400:
                    content = response.get("content", {})
                    assert "application/problem+json" in content, (path, method, code)
    activate = paths["/v1/tools/{tool_id}/versions/{version}/activate"]["post"]["responses"]
    assert "/out-of-tolerance" in activate["409"]["description"]
    rollback = paths["/v1/tools/{tool_id}/rollback"]["post"]["responses"]
    assert "/nothing-to-roll-back" in rollback["409"]["description"]
    robots = paths["/v1/robots"]["post"]["responses"]
    assert robots["409"]["description"].startswith("conflict (duplicate name")
