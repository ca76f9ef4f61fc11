"""A schemathesis check loaded with SCHEMATHESIS_HOOKS=tests.contract.hooks."""

from __future__ import annotations

from typing import Any

import schemathesis
from schemathesis import GenerationMode


@schemathesis.check
def schema_valid_is_not_refused_by_the_schema(
    ctx: Any, response: schemathesis.Response, case: schemathesis.Case[Any]
) -> bool | None:
    """A request generated to satisfy the schema may be refused for its meaning (422 with a
    domain problem type), never by request validation (/validation): that would mean the
    server enforces a constraint the spec does not state."""
    meta = case.meta
    if meta is None or meta.generation.mode != GenerationMode.POSITIVE:
        return None
    if response.status_code != 422:
        return None
    problem = response.json()
    if str(problem.get("type", "")).endswith("/validation"):
        raise AssertionError(
            f"schema-valid request refused by request validation: {problem.get('detail')}"
        )
    return None
