"""Who calls: one dependency authenticates and names the key in the access line (app.api.deps),
and every route, with a session or without, refuses a missing or too narrow key before it
reads the request (API.md: only /health and /ready are open)."""

from __future__ import annotations

from typing import Any

import pytest

from tests.conftest import Api


class _AccessLines:
    """Stands in for the access logger: keeps each line's fields."""

    def __init__(self) -> None:
        self.lines: list[dict[str, Any]] = []

    def info(self, event: str, **fields: Any) -> None:
        self.lines.append({"event": event, **fields})

    def key_of(self, method: str, route: str) -> object:
        found = [line for line in self.lines if (line["method"], line["route"]) == (method, route)]
        assert len(found) == 1, self.lines
        return found[0]["key"]


@pytest.fixture
def access(monkeypatch: pytest.MonkeyPatch) -> _AccessLines:
    lines = _AccessLines()
    monkeypatch.setattr("app.api.middleware.access_logger", lambda: lines)
    return lines


MANUAL = {"method": "manual", "tcp": {"position_mm": [1.0, 2.0, 3.0]}}


def test_every_route_refuses_a_missing_key_before_it_reads_the_request(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    client = api.client
    deployments = f"/v1/tools/{tool['id']}/deployments"
    for path, body in (
        ("/v1/solve", MANUAL),
        (f"/v1/tools/{tool['id']}/calibrations", MANUAL),
        (deployments, {}),
        ("/v1/robots", {"name": "r2"}),  # a route with a session
    ):
        for sent in ({"method": "nope"}, body):
            anonymous = client.post(path, json=sent)
            assert anonymous.status_code == 401, (path, anonymous.text)
            assert "errors" not in anonymous.json()  # nothing of the request's schema
        assert api.post(path, {"method": "nope"}, scope="admin").status_code == 422, path
    assert client.post("/v1/tools/bad!id/calibrations", json=MANUAL).status_code == 401
    assert client.post("/v1/robots/bad!id/reconcile").status_code == 401
    assert client.post(f"/v1/robots/{robot['id']}/reconcile").status_code == 401
    assert api.post("/v1/robots/bad!id/reconcile", None, scope="read").status_code == 422
    # a key of too narrow a scope: 403 before the body is looked at
    for sent in (MANUAL, {"method": "nope"}):
        refused = api.post(f"/v1/tools/{tool['id']}/calibrations", sent, scope="read")
        assert refused.status_code == 403, refused.text


def test_every_kind_of_route_names_its_key_in_the_access_line(
    api: Api, access: _AccessLines
) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    api.manual(tool["id"], [1.0, 2.0, 3.0])
    assert api.get(f"/v1/tools/{tool['id']}/tcp").status_code == 200
    assert api.post("/v1/solve", MANUAL, scope="read").status_code == 200
    assert api.post(f"/v1/robots/{robot['id']}/reconcile", scope="read").status_code == 409
    assert api.get("/v1/robots").status_code == 200
    assert access.key_of("POST", "/v1/tools/{tool_id}/calibrations") == "test-calibrate"
    assert access.key_of("GET", "/v1/tools/{tool_id}/tcp") == "test-read"
    assert access.key_of("POST", "/v1/solve") == "test-read"
    assert access.key_of("POST", "/v1/robots/{robot_id}/reconcile") == "test-read"
    assert access.key_of("GET", "/v1/robots") == "test-read"
