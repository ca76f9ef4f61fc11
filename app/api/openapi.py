"""The OpenAPI document, with the error responses the app really sends (problem+json).

FastAPI documents every 422 as its own HTTPValidationError; this app answers every error as
a Problem, so the spec is rewritten to say so, and lists the other statuses an operation can
answer (401/403 on /v1, 404 with a path id, 409/413 on writes, 412 with If-Match).
"""

from __future__ import annotations

import json

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi

from app.api.glossary import GLOSSARY
from app.jsontypes import JsonObject
from app.schemas.frame_sessions import FrameTouchAdd
from app.schemas.problems import Problem
from app.schemas.sessions import TouchAdd

#: Request bodies a route validates by hand, named in its openapi_extra: POST
#: /v1/sessions/{id}/poses takes a tool session's touch or a frame session's by the session.
BODIES_READ_BY_HAND = (TouchAdd, FrameTouchAdd)
PROBLEM_REF = {"$ref": "#/components/schemas/Problem"}
#: What FastAPI writes for a status nobody described: replaced by DESCRIPTIONS.
_FASTAPIS_WORDS = frozenset({"Validation Error", "Additional Response"})
DESCRIPTIONS = {
    "401": "no or unknown API key",
    "403": "the key's scope is too small",
    "404": "unknown or archived resource",
    "409": "conflict (duplicate name or slot, idempotency key reused)",
    "412": "If-Match does not name the current ETag",
    "413": "body larger than the limit",
    "422": "malformed or unsolvable input; `type` names the kind",
}


def _problem_content() -> JsonObject:
    """A response's content as a problem+json body (a new dict: the spec is edited in place)."""
    return {"application/problem+json": {"schema": PROBLEM_REF}}


def _problem(code: str, description: str | None = None) -> JsonObject:
    return {
        "description": description or DESCRIPTIONS.get(code, ""),
        "content": _problem_content(),
    }


def _codes(path: str, method: str, operation: JsonObject) -> list[str]:
    codes = ["422"]
    if path == "/metrics":
        return ["401", "403"]
    if path.startswith("/v1/"):
        # 404 also where an id in the body is unknown (e.g. /v1/solve's robot_id); 409 also
        # for DELETE (a key revoked twice)
        codes += ["401", "403", "404", "409"]
    if method in {"post", "patch", "put"}:
        codes.append("413")
    if any(p.get("name") == "if-match" for p in operation.get("parameters", [])):
        codes.append("412")
    return codes


def _describe_properties(model: str, schema: JsonObject) -> None:
    """Give every property without a description its meaning from the glossary."""
    for field, prop in schema.get("properties", {}).items():
        if "description" not in prop:
            meaning = GLOSSARY.get(f"{model}.{field}") or GLOSSARY.get(field)
            if meaning is not None:
                prop["description"] = meaning


def _not_nullable(parameter: JsonObject) -> None:
    """An optional query or header parameter is absent when not given, never `null`: a
    client cannot send null in a header or a query string (it would arrive as the text
    "null"), so the spec lists only the value's own schema."""
    schema = parameter.get("schema", {})
    branches = schema.get("anyOf")
    if not branches or {"type": "null"} not in branches:
        return
    rest = [b for b in branches if b != {"type": "null"}]
    if len(rest) == 1:
        del schema["anyOf"]
        schema.update(rest[0])


def _add_bodies_read_by_hand(schemas: JsonObject) -> None:
    """The schemas of BODIES_READ_BY_HAND, written as FastAPI writes a body's."""
    for model in BODIES_READ_BY_HAND:
        schema = model.model_json_schema(ref_template="#/components/schemas/{model}")
        schemas.update(schema.pop("$defs", {}))
        for field in schema.get("properties", {}).values():
            if field.get("default", ...) is None:
                del field["default"]  # as FastAPI writes an optional body field
        schemas[model.__name__] = schema


def build_openapi(app: FastAPI) -> JsonObject:
    """The app's OpenAPI document with problem+json error responses."""
    if app.openapi_schema:
        return app.openapi_schema
    spec = get_openapi(title=app.title, version=app.version, summary=app.summary, routes=app.routes)
    schemas = spec.setdefault("components", {}).setdefault("schemas", {})
    problem = Problem.model_json_schema(ref_template="#/components/schemas/{model}")
    schemas.update(problem.pop("$defs", {}))
    schemas["Problem"] = problem
    _add_bodies_read_by_hand(schemas)
    for path, item in spec.get("paths", {}).items():
        for method, operation in item.items():
            if path in {"/health", "/ready"}:
                continue
            for parameter in operation.get("parameters", []):
                _not_nullable(parameter)
            responses = operation.setdefault("responses", {})
            for code in _codes(path, method, operation):
                # a route's own words for a status (activate's 409 is /out-of-tolerance) stay
                said = responses.get(code, {}).get("description")
                responses[code] = _problem(code, None if said in _FASTAPIS_WORDS else said)
            for code, response in responses.items():
                if code.isdigit() and int(code) >= 400 and "content" not in response:
                    response["content"] = _problem_content()  # e.g. deploy's 502
    for unused in ("HTTPValidationError", "ValidationError"):
        schemas.pop(unused, None)
    for model, schema in schemas.items():
        _describe_properties(model, schema)
    app.openapi_schema = spec
    return spec


def openapi_text(app: FastAPI) -> str:
    """The document as committed in openapi/openapi.json, byte for byte."""
    return json.dumps(app.openapi(), indent=2, sort_keys=True) + "\n"
