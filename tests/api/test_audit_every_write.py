"""Every write route of the app leaves an audit event, with its actor and request id, in the
transaction of the change; the audit of a key change never holds the key.

The routes are enumerated from the app itself (every POST/PUT/PATCH/DELETE under /v1): a new
write route that is not in CALLS below fails `test_every_write_route_is_in_the_table`, and one
that writes no event fails `test_every_write_route_leaves_an_audit_event`.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, get_args
from uuid import uuid4

import numpy as np
import pytest
from fastapi.routing import iter_route_contexts
from sqlalchemy import text

from app.kinematics.poses import pose_to_format
from app.words import AuditAction, ResourceType
from testbed.sim.touches import simulate_touches
from tests.api.controller_rigs import Rig, rig
from tests.api.frame_fiducials import calibrated_frame, cell, touches
from tests.api.frame_versions import add_frame_version
from tests.api.touches import as_poses
from tests.conftest import Api

WRITE_METHODS = {"POST", "PUT", "PATCH", "DELETE"}
TCP = [0.0, 0.0, 150.0]
POINT = [800.0, 50.0, 300.0]


@dataclass
class Call:
    """One request to a route: where, with what, and whether it changes anything."""

    url: str
    body: Any = None
    headers: dict[str, str] = field(default_factory=dict)
    scope: str = "admin"
    writes: bool = True


def _robot(api: Api) -> str:
    return str(api.robot(f"r-{uuid4().hex[:8]}", cell="cell-1")["id"])


def _tool(api: Api, *, active: bool = True) -> dict[str, Any]:
    tool = api.tool(_robot(api), "torch", slot=1)
    if active:
        api.manual(tool["id"], TCP)
    return tool


def _touch_at_point() -> list[float]:
    """A flange pose that puts TCP on POINT, the tool pointing down."""
    rotation = np.diag([1.0, -1.0, -1.0])  # 180 deg about x
    flange = np.asarray(POINT) - rotation @ np.asarray(TCP)
    return [float(v) for v in pose_to_format("xyz_wxyz", rotation, flange)]  # type: ignore[arg-type]


def _touches(n: int = 6) -> list[Any]:
    return as_poses(
        simulate_touches(n, seed=7, tcp_mm=np.asarray(TCP), touch_noise_mm=0.02), "kuka_abc"
    )


def _session(api: Api, touches: int) -> str:
    tool = _tool(api)
    made = api.post(
        f"/v1/tools/{tool['id']}/sessions",
        {"method": "xyz_npoint", "format": "kuka_abc"},
        scope="calibrate",
    )
    assert made.status_code == 201, made.text
    sid = str(made.json()["id"])
    for pose in _touches()[:touches]:
        added = api.post(f"/v1/sessions/{sid}/poses", {"pose": pose}, scope="calibrate")
        assert added.status_code == 200, added.text
    return sid


def _reference(api: Api, robot_id: str) -> str:
    made = api.post(
        f"/v1/robots/{robot_id}/reference-points", {"name": "pin", "position_mm": POINT}
    )
    assert made.status_code == 201, made.text
    return str(made.json()["id"])


def _check(api: Api, _rig: Rig) -> Call:
    tool = _tool(api)
    point = _reference(api, tool["robot_id"])
    body = {"reference_point_id": point, "format": "xyz_wxyz", "poses": [_touch_at_point()]}
    return Call(f"/v1/tools/{tool['id']}/checks", body, scope="calibrate")


def _activate(api: Api, _rig: Rig) -> Call:
    tool = _tool(api)
    api.manual(tool["id"], [0.0, 0.0, 151.0])
    return Call(f"/v1/tools/{tool['id']}/versions/1/activate", scope="calibrate")


def _revoke(api: Api, _rig: Rig) -> Call:
    made = api.post("/v1/keys", {"name": "doomed", "scope": "read"})
    return Call(f"/v1/keys/{made.json()['id']}")


#: How to call each write route with a valid request (its prerequisites made first).
def _rollback(api: Api, _rig: Rig) -> Call:
    tool = _tool(api)
    api.manual(tool["id"], [0.0, 0.0, 151.0])  # v2 active, v1 before it
    return Call(f"/v1/tools/{tool['id']}/rollback", scope="calibrate")


def _frame(api: Api, *, versions: int = 0) -> str:
    """A frame of a new robot, with `versions` stored versions (the first active)."""
    made = api.post(f"/v1/robots/{_robot(api)}/frames", {"name": "fixture", "kind": "base"})
    assert made.status_code == 201, made.text
    fid = str(made.json()["id"])
    for n in range(1, versions + 1):
        add_frame_version(fid, [500.0 + n, 0.0, 0.0])
        activated = api.post(f"/v1/frames/{fid}/versions/{n}/activate", scope="calibrate")
        assert activated.status_code == 200, activated.text
    return fid


def _touched_frame(api: Api) -> str:
    """A frame calibrated by three_point with a pointer tool: it keeps three fiducials."""
    tool = _tool(api)  # TCP [0, 0, 150], pointing down in the poses below
    made = api.post(f"/v1/robots/{tool['robot_id']}/frames", {"name": "f", "kind": "base"})
    fid = str(made.json()["id"])
    down = [0.0, 1.0, 0.0, 0.0]
    touches = [
        {"role": role, "pose": [*xyz, *down]}
        for role, xyz in (("origin", [900, 0, 700]), ("x", [1300, 0, 700]), ("xy", [900, 300, 700]))
    ]
    body = {"method": "three_point", "tool_id": tool["id"], "format": "xyz_wxyz",
            "touches": touches, "options": {"touch_noise_mm": 0.05}}  # fmt: skip
    calibrated = api.post(f"/v1/frames/{fid}/calibrations", body, scope="calibrate")
    assert calibrated.status_code == 201, calibrated.text
    return fid


def _frame_session(api: Api, _rig: Rig) -> Call:
    tool = _tool(api)
    made = api.post(f"/v1/robots/{tool['robot_id']}/frames", {"name": "f", "kind": "base"})
    body = {"method": "three_point", "tool_id": tool["id"], "format": "xyz_wxyz"}
    return Call(f"/v1/frames/{made.json()['id']}/sessions", body, scope="calibrate")


def _frame_activate(api: Api, _rig: Rig) -> Call:
    fid = _frame(api, versions=1)
    add_frame_version(fid, [510.0, 0.0, 0.0])
    return Call(f"/v1/frames/{fid}/versions/2/activate", {"reason": "taught"}, scope="calibrate")


def _frame_check(api: Api, _rig: Rig) -> Call:
    """A robot-wide correction of a robot with one frame and one reference point."""
    robot, pointer = cell(api)
    R, o = np.eye(3), np.array([500.0, 0.0, 0.0])
    fid = calibrated_frame(api, robot["id"], "fixture", R, o, pointer_id=pointer["id"])["id"]
    _reference(api, robot["id"])
    body = {**touches(pointer["id"], R, o + np.array([1.0, 0.0, 0.0])), "correct": "within_limits"}
    return Call(f"/v1/frames/{fid}/checks", {**body, "scope": "robot"}, scope="calibrate")


def _on_controller(api: Api, rig: Rig, *, active: bool = True) -> dict[str, Any]:
    """A tool of a robot whose controller is the rig's simulator."""
    tool = api.tool(_robot(api), "torch", **rig.tool_fields)
    put = api.request("PUT", f"/v1/robots/{tool['robot_id']}/controller", "admin",
                      json=rig.controller_body())  # fmt: skip
    assert put.status_code == 200, put.text
    if active:
        api.manual(tool["id"], TCP)
    return tool


def _frame_deploy(api: Api, rig: Rig) -> Call:
    """A frame with an active version, at BASE_DATA[3] of a robot on the rig's controller."""
    robot_id = _robot(api)
    put = api.request("PUT", f"/v1/robots/{robot_id}/controller", "admin",
                      json=rig.controller_body())  # fmt: skip
    assert put.status_code == 200, put.text
    made = api.post(f"/v1/robots/{robot_id}/frames", {"name": "table", "kind": "base", "slot": 3})
    assert made.status_code == 201, made.text
    fid = str(made.json()["id"])
    add_frame_version(fid, [500.0, 0.0, 0.0])
    activated = api.post(f"/v1/frames/{fid}/versions/1/activate", scope="calibrate")
    assert activated.is_success, activated.text
    return Call(f"/v1/frames/{fid}/deployments", {}, scope="calibrate")


def _controller_delete(api: Api, rig: Rig) -> Call:
    return Call(f"/v1/robots/{_on_controller(api, rig, active=False)['robot_id']}/controller")


#: How to call each write route with a valid request (its prerequisites made first; `Rig` is a
#: KUKA controller simulator for the routes that talk to a controller).
CALLS: dict[tuple[str, str], Callable[[Api, Rig], Call]] = {
    ("POST", "/v1/robots"): lambda api, _rig: Call("/v1/robots", {"name": "new", "cell": "cell-1"}),
    ("PATCH", "/v1/robots/{robot_id}"): lambda api, _rig: Call(
        f"/v1/robots/{_robot(api)}", {"cell": "cell-2"}
    ),
    ("DELETE", "/v1/robots/{robot_id}"): lambda api, _rig: Call(f"/v1/robots/{_robot(api)}"),
    ("POST", "/v1/robots/{robot_id}/tools"): lambda api, _rig: Call(
        f"/v1/robots/{_robot(api)}/tools", {"name": "gripper"}
    ),
    ("PATCH", "/v1/tools/{tool_id}"): lambda api, _rig: Call(
        f"/v1/tools/{_tool(api, active=False)['id']}", {"tolerance": {"max_rms_mm": 0.2}}
    ),
    ("DELETE", "/v1/tools/{tool_id}"): lambda api, _rig: Call(
        f"/v1/tools/{_tool(api, active=False)['id']}"
    ),
    ("POST", "/v1/tools/{tool_id}/calibrations"): lambda api, _rig: Call(
        f"/v1/tools/{_tool(api, active=False)['id']}/calibrations",
        {"method": "manual", "tcp": {"position_mm": TCP}},
        scope="calibrate",
    ),
    ("POST", "/v1/tools/{tool_id}/versions/{version}/activate"): _activate,
    ("POST", "/v1/tools/{tool_id}/checks"): _check,
    ("POST", "/v1/tools/{tool_id}/rollback"): _rollback,
    ("PUT", "/v1/robots/{robot_id}/controller"): lambda api, rig: Call(
        f"/v1/robots/{_robot(api)}/controller", rig.controller_body()
    ),
    ("DELETE", "/v1/robots/{robot_id}/controller"): _controller_delete,
    ("POST", "/v1/tools/{tool_id}/deployments"): lambda api, rig: Call(
        f"/v1/tools/{_on_controller(api, rig)['id']}/deployments", {}, scope="calibrate"
    ),
    ("POST", "/v1/robots/{robot_id}/reconcile"): lambda api, rig: Call(
        f"/v1/robots/{_on_controller(api, rig)['robot_id']}/reconcile", scope="read"
    ),
    ("POST", "/v1/robots/{robot_id}/reference-points"): lambda api, _rig: Call(
        f"/v1/robots/{_robot(api)}/reference-points",
        {"name": "pin", "position_mm": POINT},
        scope="calibrate",
    ),
    ("POST", "/v1/robots/{robot_id}/laser-devices"): lambda api, _rig: Call(
        f"/v1/robots/{_robot(api)}/laser-devices",
        {"name": "beams", "beam_a_y_mm": 10.0, "beam_b_x_mm": -5.0, "plane_z_mm": 100.0},
        scope="calibrate",
    ),
    ("POST", "/v1/keys"): lambda api, _rig: Call("/v1/keys", {"name": "cell-pc", "scope": "read"}),
    ("DELETE", "/v1/keys/{key_id}"): _revoke,
    ("POST", "/v1/tools/{tool_id}/sessions"): lambda api, _rig: Call(
        f"/v1/tools/{_tool(api)['id']}/sessions",
        {"method": "xyz_npoint", "format": "kuka_abc"},
        scope="calibrate",
    ),
    ("POST", "/v1/sessions/{session_id}/poses"): lambda api, _rig: Call(
        f"/v1/sessions/{_session(api, 0)}/poses", {"pose": _touches()[0]}, scope="calibrate"
    ),
    ("DELETE", "/v1/sessions/{session_id}/poses/{index}"): lambda api, _rig: Call(
        f"/v1/sessions/{_session(api, 2)}/poses/1", scope="calibrate"
    ),
    ("POST", "/v1/sessions/{session_id}/finish"): lambda api, _rig: Call(
        f"/v1/sessions/{_session(api, 6)}/finish", {}, scope="calibrate"
    ),
    ("POST", "/v1/robots/{robot_id}/frames"): lambda api, _rig: Call(
        f"/v1/robots/{_robot(api)}/frames", {"name": "fixture-a", "kind": "base"}
    ),
    ("PATCH", "/v1/frames/{frame_id}"): lambda api, _rig: Call(
        f"/v1/frames/{_frame(api)}", {"tolerance": {"max_change_mm": 2.0}}
    ),
    ("DELETE", "/v1/frames/{frame_id}"): lambda api, _rig: Call(f"/v1/frames/{_frame(api)}"),
    ("POST", "/v1/frames/{frame_id}/versions/{version}/activate"): _frame_activate,
    ("POST", "/v1/frames/{frame_id}/calibrations"): lambda api, _rig: Call(
        f"/v1/frames/{_frame(api)}/calibrations",
        {"method": "manual", "frame": {"position_mm": [500.0, 0.0, 0.0]}},
        scope="calibrate",
    ),
    ("POST", "/v1/frames/{frame_id}/sessions"): _frame_session,
    ("PUT", "/v1/frames/{frame_id}/fiducials"): lambda api, _rig: Call(
        f"/v1/frames/{_touched_frame(api)}/fiducials", {"names": ["a", "b", "c"]}, scope="calibrate"
    ),
    ("POST", "/v1/frames/{frame_id}/checks"): _frame_check,
    ("POST", "/v1/frames/{frame_id}/deployments"): _frame_deploy,
    ("POST", "/v1/frames/{frame_id}/rollback"): lambda api, _rig: Call(
        f"/v1/frames/{_frame(api, versions=2)}/rollback", scope="calibrate"
    ),
    # POSTs that compute and store nothing: called too, and must leave no event.
    ("POST", "/v1/plan"): lambda api, _rig: Call(
        "/v1/plan",
        {"format": "kuka_abc", "start": _touches()[0], "tcp_mm": TCP},
        scope="read",
        writes=False,
    ),
    ("POST", "/v1/solve"): lambda api, _rig: Call(
        "/v1/solve",
        {"method": "xyz_npoint", "format": "kuka_abc", "poses": _touches()},
        scope="read",
        writes=False,
    ),
}


#: What each write route is, as its audit events must say: (action, resource_type, where the
#: resource's id is) for every event, in the order written. Where: "{param}" the request
#: path's, else a path into the response's body ("id": the resource it made).
EVENTS: dict[tuple[str, str], tuple[tuple[str, str, str], ...]] = {
    ("POST", "/v1/robots"): (("robot.create", "robot", "id"),),
    ("PATCH", "/v1/robots/{robot_id}"): (("robot.update", "robot", "{robot_id}"),),
    ("DELETE", "/v1/robots/{robot_id}"): (("robot.archive", "robot", "{robot_id}"),),
    ("POST", "/v1/robots/{robot_id}/tools"): (("tool.create", "tool", "id"),),
    ("PATCH", "/v1/tools/{tool_id}"): (("tool.update", "tool", "{tool_id}"),),
    ("DELETE", "/v1/tools/{tool_id}"): (("tool.archive", "tool", "{tool_id}"),),
    ("POST", "/v1/tools/{tool_id}/calibrations"): (
        ("version.create", "tool", "{tool_id}"),
        ("version.activate", "tool", "{tool_id}"),  # a manual TCP is active at once
        ("calibration.create", "calibration", "id"),
    ),
    ("POST", "/v1/tools/{tool_id}/versions/{version}/activate"): (
        ("version.activate", "tool", "{tool_id}"),
    ),
    ("POST", "/v1/tools/{tool_id}/checks"): (("tool.check", "tool", "{tool_id}"),),
    ("POST", "/v1/tools/{tool_id}/rollback"): (("version.rollback", "tool", "{tool_id}"),),
    ("PUT", "/v1/robots/{robot_id}/controller"): (("controller.set", "robot", "{robot_id}"),),
    ("DELETE", "/v1/robots/{robot_id}/controller"): (("controller.delete", "robot", "{robot_id}"),),
    ("POST", "/v1/tools/{tool_id}/deployments"): (
        ("tool.deploy", "deployment", "id"),
        ("controller.in_sync", "tool", "{tool_id}"),  # read back: the controller holds it
    ),
    ("POST", "/v1/robots/{robot_id}/reconcile"): (
        ("robot.live_tool", "robot", "robot_id"),  # the first read of what it moves by
        ("controller.drifted", "tool", "tools.0.tool_id"),  # the simulator holds another
    ),
    ("POST", "/v1/robots/{robot_id}/reference-points"): (
        ("reference_point.create", "reference_point", "id"),
    ),
    ("POST", "/v1/robots/{robot_id}/laser-devices"): (
        ("laser_device.create", "laser_device", "id"),
    ),
    ("POST", "/v1/keys"): (("key.create", "api_key", "id"),),
    ("DELETE", "/v1/keys/{key_id}"): (("key.revoke", "api_key", "{key_id}"),),
    ("POST", "/v1/tools/{tool_id}/sessions"): (("session.create", "session", "id"),),
    ("POST", "/v1/frames/{frame_id}/sessions"): (("session.create", "session", "id"),),
    ("POST", "/v1/sessions/{session_id}/poses"): (
        ("session.touch_add", "session", "{session_id}"),
    ),
    ("DELETE", "/v1/sessions/{session_id}/poses/{index}"): (
        ("session.touch_delete", "session", "{session_id}"),
    ),
    ("POST", "/v1/sessions/{session_id}/finish"): (
        ("version.create", "tool", "tool_id"),
        ("version.activate", "tool", "tool_id"),
        ("calibration.create", "calibration", "id"),
        ("session.finish", "session", "{session_id}"),
    ),
    ("POST", "/v1/robots/{robot_id}/frames"): (("frame.create", "frame", "id"),),
    ("PATCH", "/v1/frames/{frame_id}"): (("frame.update", "frame", "{frame_id}"),),
    ("DELETE", "/v1/frames/{frame_id}"): (("frame.archive", "frame", "{frame_id}"),),
    ("POST", "/v1/frames/{frame_id}/versions/{version}/activate"): (
        ("version.activate", "frame", "{frame_id}"),
    ),
    ("POST", "/v1/frames/{frame_id}/rollback"): (("version.rollback", "frame", "{frame_id}"),),
    ("POST", "/v1/frames/{frame_id}/calibrations"): (
        ("version.create", "frame", "{frame_id}"),
        ("version.activate", "frame", "{frame_id}"),  # a manual frame is active at once
        ("calibration.create", "calibration", "id"),
    ),
    ("PUT", "/v1/frames/{frame_id}/fiducials"): (("frame.fiducials", "frame", "{frame_id}"),),
    ("POST", "/v1/frames/{frame_id}/deployments"): (
        ("frame.deploy", "deployment", "id"),
        ("controller.in_sync", "frame", "{frame_id}"),  # read back: the controller holds it
    ),
    ("POST", "/v1/frames/{frame_id}/checks"): (
        ("frame.check", "frame", "{frame_id}"),
        ("version.create", "frame", "{frame_id}"),
        ("version.activate", "frame", "{frame_id}"),
        ("reference_point.move", "reference_point", "correction.moved.0.id"),
    ),
}


#: The actions no write route records, and the tests that show them recorded.
RECORDED_BY_A_ROUND: dict[str, str] = {
    "controller.unreachable": "a reconcile round that cannot reach the controller "
    "(tests/services/controllers/test_watcher.py)",
    "deployment.settled": "the reconcile round after an unverified deployment "
    "(tests/api/test_deployments.py, tests/services/controllers/test_watcher.py)",
}


def test_the_routes_record_the_audit_actions_and_nothing_else() -> None:
    """Every action and resource type a write route records (EVENTS, which the test below
    holds to what the routes record) is a word of AuditAction and ResourceType, the Literals
    the rows and the trail are typed with; and every word of those is recorded by a route or
    by a reconcile round (RECORDED_BY_A_ROUND), so neither lists a word nothing writes."""
    actions = {action for events in EVENTS.values() for action, _kind, _where in events}
    kinds = {kind for events in EVENTS.values() for _action, kind, _where in events}
    assert sorted(actions - set(get_args(AuditAction))) == []
    assert sorted(kinds - set(get_args(ResourceType))) == []
    assert set(get_args(AuditAction)) - actions == set(RECORDED_BY_A_ROUND)
    assert set(get_args(ResourceType)) == kinds


def write_routes() -> list[tuple[str, str]]:
    """Every (method, path) of the app that is not a read, under /v1, each path as the
    contract writes it: a parameter's convertor (/v1/keys/{key_id:key_id}, which refuses the
    reserved 'me') is how the route matches, not a part of the path."""
    from app.main import create_app

    found = set()
    for route in iter_route_contexts(create_app().routes):  # the included routers' too
        if route.path is not None and route.path.startswith("/v1/"):
            path = re.sub(r"\{(\w+):[^}]+\}", r"{\1}", route.path)
            for method in (route.methods or set()) & WRITE_METHODS:
                found.add((method, path))
    return sorted(found)


def test_every_write_route_is_in_the_table() -> None:
    routes = write_routes()
    missing = [r for r in routes if r not in CALLS]
    assert missing == [], (
        f"write routes without an entry in CALLS: {missing}; add how to call each, and make "
        "its service record an audit event (app.services.audit.writes) in the same transaction"
    )
    stale = [r for r in CALLS if r not in routes]
    assert stale == [], f"CALLS names routes the app no longer has: {stale}"
    assert [r for r in EVENTS if r not in CALLS] == [], "EVENTS names routes CALLS does not"


def _events(api: Api) -> list[dict[str, Any]]:
    from app.storage.db import get_engine

    with get_engine().connect() as conn:
        rows = conn.execute(text("SELECT * FROM audit_events ORDER BY id")).mappings().all()
    return [dict(r) for r in rows]


@pytest.mark.parametrize("route", sorted(CALLS), ids=lambda r: f"{r[0]} {r[1]}")
def test_every_write_route_leaves_an_audit_event(api: Api, route: tuple[str, str]) -> None:
    with rig("kuka_kvp") as kuka:
        _leaves_its_events(api, route, CALLS[route](api, kuka))


def _path_params(template: str, url: str) -> dict[str, str]:
    pattern = re.sub(r"\\{(\w+)\\}", r"(?P<\1>[^/]+)", re.escape(template))
    match = re.fullmatch(pattern, url)
    assert match is not None, (template, url)
    return match.groupdict()


def _resource_id(where: str, params: dict[str, str], body: Any) -> str:
    """The id an event must name, from the request's path ("{param}") or its answer."""
    if where.startswith("{"):
        return params[where.strip("{}")]
    for part in where.split("."):
        body = body[int(part)] if part.isdigit() else body[part]
    return str(body)


def _leaves_its_events(api: Api, route: tuple[str, str], call: Call) -> None:
    method, template = route
    before = len(_events(api))
    request_id = f"audit-test-{uuid4().hex}"
    kw: dict[str, Any] = {"headers": {"X-Request-ID": request_id, **call.headers}}
    if call.body is not None:
        kw["json"] = call.body
    response = api.request(method, call.url, call.scope, **kw)
    assert response.status_code < 300, response.text
    new = _events(api)[before:]
    if not call.writes:
        assert new == []
        return
    assert new, f"{method} {call.url} changed something and left no audit event"
    assert route in EVENTS, f"add {route} to EVENTS: the action and resource of its events"
    # What the route is: each event's action, resource and the resource's id.
    params = _path_params(template, call.url)
    body = response.json() if response.content else None
    expected = [
        (action, kind, _resource_id(where, params, body)) for action, kind, where in EVENTS[route]
    ]
    assert [(e["action"], e["resource_type"], e["resource_id"]) for e in new] == expected
    assert {e["action"] for e in new} <= set(get_args(AuditAction))
    for event in new:
        assert event["actor"] == f"test-{call.scope}", event
        assert event["request_id"] == request_id, event
        assert event["at"] is not None
        for column in ("robot_id", "tool_id", "frame_id"):  # the robot or subject the path names
            if column in params:
                assert event[column] == params[column], (column, event)
    # And readable through the API, with the same request id.
    trail = api.get("/v1/audit", scope="admin", params={"limit": 500}).json()["items"]
    ids = {str(e["id"]) for e in new}
    shown = [e for e in trail if e["id"] in ids]
    assert len(shown) == len(new)
    assert {e["request_id"] for e in shown} == {request_id}


def _robot_names(api: Api) -> list[str]:
    return [r["name"] for r in api.get("/v1/robots", params={"limit": 500}).json()["items"]]


def test_an_event_and_its_change_commit_or_roll_back_together(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One transaction: when the event's insert fails the robot is not created either, and
    when the commit fails after the event was inserted (the outbox row, written last in the
    transaction) neither is kept. Then, unbroken, both are."""
    from app.services.audit import outbox
    from app.services.audit import writes as audit

    def broken(*_: object) -> None:
        raise RuntimeError("planted by the test")

    for module, name in ((audit._INSERT, "execute"), (outbox, "write")):
        with monkeypatch.context() as patch:
            patch.setattr(module, name, broken)
            before = _events(api)
            r = api.post("/v1/robots", {"name": f"lost-{name}", "cell": "cell-1"})
            assert r.status_code == 500, r.text
            assert _events(api) == before, name  # no event...
            assert f"lost-{name}" not in _robot_names(api), name  # ...and no robot
    made = api.post("/v1/robots", {"name": "kept", "cell": "cell-1"})
    assert made.status_code == 201, made.text
    assert "kept" in _robot_names(api)
    (event,) = [e for e in _events(api) if e["resource_id"] == made.json()["id"]]
    assert event["action"] == "robot.create"


def test_the_audit_of_a_key_change_never_holds_the_key(api: Api) -> None:
    from app.security.auth import hash_key

    made = api.post("/v1/keys", {"name": "cell-12 pc", "scope": "calibrate", "cells": ["cell-12"]})
    assert made.status_code == 201, made.text
    secret, key_id = made.json()["key"], made.json()["id"]
    assert api.delete(f"/v1/keys/{key_id}").status_code == 204
    rows = [r for r in _events(api) if r["resource_id"] == key_id]
    assert [r["action"] for r in rows] == ["key.create", "key.revoke"]
    everything = json.dumps(_events(api), default=str)
    assert secret not in everything
    assert hash_key(secret) not in everything
    assert secret[7:12] not in everything  # not even the part of the key a prefix shows
    created = rows[0]
    details = created["details"] if isinstance(created["details"], dict) else None
    if details is None:
        details = json.loads(created["details"])
    assert details == {"name": "cell-12 pc", "scope": "calibrate", "cells": ["cell-12"]}
