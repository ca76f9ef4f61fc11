"""The example body of every method (shown in the OpenAPI spec) solves, stateless and stored."""

from __future__ import annotations

import pytest

from app.methods import METHODS
from app.methods.base import RegisteredMethod
from tests.conftest import Api


@pytest.mark.parametrize("method", METHODS, ids=[m.name for m in METHODS])
def test_example_solves_accepted(api: Api, method: RegisteredMethod) -> None:
    response = api.post("/v1/solve", method.example, scope="read")
    assert response.status_code == 200, response.text
    result = response.json()
    assert result["method"] == method.name
    assert result["status"] == "accepted", result["summary"]

    robot = api.robot()
    tool = api.tool(robot["id"], load={"mass_kg": 2.0, "cog_mm": [0, 0, 60]})
    stored = api.post(f"/v1/tools/{tool['id']}/calibrations", method.example, scope="calibrate")
    assert stored.status_code == 201, stored.text
    assert stored.json()["tcp"] == result["tcp"]


def test_the_spec_carries_one_example_per_method(api: Api) -> None:
    spec = api.get("/openapi.json").json()
    for path, verb in (("/v1/solve", "post"), ("/v1/tools/{tool_id}/calibrations", "post")):
        content = spec["paths"][path][verb]["requestBody"]["content"]["application/json"]
        assert set(content["examples"]) == {m.name for m in METHODS}
