"""The steps every capture test takes against a controller simulator (issue 39): a robot on
the rig's controller with a tool the controller can address, a guided session, its finish."""

from __future__ import annotations

from typing import Any

from tests.api.controller_rigs import Rig
from tests.conftest import Api


def tool_on(api: Api, r: Rig, robot: str = "r1", **controller: Any) -> dict[str, Any]:
    """A robot on `r`'s controller (`controller` overrides its settings) with a tool "torch"
    in the rig's slot or symbol."""
    made = api.robot(robot)
    body = r.controller_body(**controller)
    put = api.request("PUT", f"/v1/robots/{made['id']}/controller", "admin", json=body)
    assert put.status_code == 200, put.text
    return api.tool(made["id"], "torch", **r.tool_fields)


def guided_session(api: Api, tool_id: str, fmt: str, **options: float) -> str:
    """A new xyz_npoint session of the tool, touches in `fmt`; its id."""
    body: dict[str, Any] = {"method": "xyz_npoint", "format": fmt}
    if options:
        body["options"] = options
    created = api.post(f"/v1/tools/{tool_id}/sessions", body, scope="calibrate")
    assert created.status_code == 201, created.text
    return str(created.json()["id"])


def finish(api: Api, sid: str) -> dict[str, Any]:
    """The calibration the session finishes to, not activated."""
    done = api.post(f"/v1/sessions/{sid}/finish", {"activate": "never"}, scope="calibrate")
    assert done.status_code == 201, done.text
    return dict(done.json())
