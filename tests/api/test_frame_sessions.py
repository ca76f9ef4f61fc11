"""Guided frame sessions over HTTP (API.md v1.4 "Sessions:"): a base touched role by role with
a pointer tool, typed or captured from the robot's controller, the next touch said in words
with the distance the angle tolerance needs, finished as the frame calibration POST
/v1/frames/{id}/calibrations stores; a tool's session is untouched by them."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_to_format
from tests.api.capture_steps import tool_on
from tests.api.controller_rigs import rig
from tests.api.test_capture_controllers import SETUPS
from tests.api.test_capture_controllers import secret_key as secret_key  # autouse
from tests.conftest import Api

POINTER_TCP = [0.0, 0.0, 150.0]
#: The fixture's base in the robot's base frame: origin, +X and a point on its +Y side.
ORIGIN = np.array([800.0, -200.0, 400.0])
TURN = Rotation.from_euler("z", 30, degrees=True)
X_AT = ORIGIN + TURN.apply([300.0, 0.0, 0.0])
XY_AT = ORIGIN + TURN.apply([40.0, 250.0, 0.0])
DOWN = Rotation.from_euler("x", 180, degrees=True)  # the pointer pointing down


def _pose(point: np.ndarray) -> list[float]:
    """The flange pose (kuka_abc) that puts the pointer's TCP on `point`."""
    flange = point - DOWN.apply(POINTER_TCP)
    return [float(v) for v in np.ravel(pose_to_format("kuka_abc", DOWN.as_matrix(), flange))]


def _setup(api: Api, robot: dict[str, Any] | None = None) -> tuple[str, str]:
    """A frame of a robot and its pointer tool with an active TCP: (frame id, tool id)."""
    robot = robot or api.robot("kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "pointer")
    api.manual(tool["id"], POINTER_TCP)
    made = api.post(
        f"/v1/robots/{robot['id']}/frames", {"name": "fixture-a", "kind": "base", "slot": 2}
    )
    assert made.status_code == 201, made.text
    return made.json()["id"], tool["id"]


def _session(api: Api, frame_id: str, tool_id: str, **options: Any) -> dict[str, Any]:
    body = {"method": "three_point", "tool_id": tool_id, "format": "kuka_abc",
            "options": {"touch_noise_mm": 0.05, **options}}  # fmt: skip
    created = api.post(f"/v1/frames/{frame_id}/sessions", body, scope="calibrate")
    assert created.status_code == 201, created.text
    return dict(created.json())


def _touch(api: Api, sid: str, **body: Any) -> Any:
    return api.post(f"/v1/sessions/{sid}/poses", body, scope="calibrate")


def test_three_touches_guided_by_role_finish_as_the_frame_calibration(api: Api) -> None:
    frame_id, tool_id = _setup(api)
    started = _session(api, frame_id, tool_id)
    assert started["frame_id"] == frame_id
    assert started["next_role"] == "touch the frame's origin"
    assert started["next"] == {"role": "origin", "takes": "role"}
    assert started["done"] is False
    after_origin = _touch(api, started["id"], role="origin", pose=_pose(ORIGIN))
    assert after_origin.status_code == 200, after_origin.text
    assert after_origin.json()["next_role"] == (
        "touch a point on the frame's +X axis, at least 82 mm from the origin touch"
    )
    np.testing.assert_allclose(after_origin.json()["touches"][0]["point_mm"], ORIGIN, atol=1e-9)
    assert _touch(api, started["id"], role="x", pose=_pose(X_AT)).status_code == 200
    last = _touch(api, started["id"], role="xy", pose=_pose(XY_AT))
    assert last.status_code == 200, last.text
    state = last.json()
    assert state["done"] is True, state["messages"]
    assert state["next_role"] is None
    assert [t["role"] for t in state["touches"]] == ["origin", "x", "xy"]
    np.testing.assert_allclose(state["estimate"]["position_mm"], ORIGIN, atol=1e-9)

    finished = api.post(f"/v1/sessions/{started['id']}/finish", scope="calibrate")
    assert finished.status_code == 201, finished.text
    calibration = finished.json()
    assert calibration["frame_id"] == frame_id
    assert calibration["method"] == "three_point"
    assert calibration["version"] == 1
    np.testing.assert_allclose(calibration["frame"]["position_mm"], ORIGIN, atol=1e-9)
    q = calibration["frame"]["quaternion"]
    turned = Rotation.from_quat(q, scalar_first=True) * TURN.inv()
    assert turned.magnitude() < 1e-9
    assert calibration["quality"]["position_sigma_mm"] is not None
    session = api.get(f"/v1/sessions/{started['id']}").json()
    assert (session["status"], session["calibration_id"]) == ("finished", calibration["id"])
    again = api.post(f"/v1/sessions/{started['id']}/finish", scope="calibrate")
    assert again.status_code == 409, again.text
    listed = api.get(f"/v1/frames/{frame_id}/calibrations").json()["items"]
    assert [c["id"] for c in listed] == [calibration["id"]]


def test_a_touch_not_what_the_method_takes_is_refused_and_not_kept(api: Api) -> None:
    frame_id, tool_id = _setup(api)
    sid = _session(api, frame_id, tool_id)["id"]
    bare = _touch(api, sid, pose=_pose(ORIGIN))
    assert bare.status_code == 422, bare.text
    assert bare.json()["errors"][0]["loc"] == ["body", "role"]
    assert "next is 'origin' (touch the frame's origin)" in bare.json()["detail"]
    assert _touch(api, sid, role="origin", pose=_pose(ORIGIN)).status_code == 200
    twice = _touch(api, sid, role="origin", pose=_pose(X_AT))
    assert twice.status_code == 422, twice.text
    assert twice.json()["type"].endswith("/repeated-role")
    assert f"DELETE /v1/sessions/{sid}/poses/0" in twice.json()["detail"]
    nominal = _touch(api, sid, nominal_mm=[0, 0, 0], pose=_pose(X_AT))
    assert nominal.status_code == 422, nominal.text
    assert nominal.json()["errors"][0]["loc"] == ["body", "nominal_mm"]
    unknown = _touch(api, sid, role="x", pose=_pose(X_AT), speed=3)
    assert unknown.status_code == 422, unknown.text
    assert unknown.json()["errors"][0]["loc"] == ["body", "speed"]
    assert api.get(f"/v1/sessions/{sid}").json()["n_touches"] == 1


def test_an_x_touch_too_close_is_said_before_finishing(api: Api) -> None:
    frame_id, tool_id = _setup(api)
    sid = _session(api, frame_id, tool_id)["id"]
    near = ORIGIN + TURN.apply([60.0, 0.0, 0.0])
    for role, point in (("origin", ORIGIN), ("x", near), ("xy", XY_AT)):
        assert _touch(api, sid, role=role, pose=_pose(point)).status_code == 200
    state = api.get(f"/v1/sessions/{sid}").json()
    assert state["done"] is False
    assert any("at least 82 mm from it" in m for m in state["messages"]), state["messages"]
    refused = api.post(f"/v1/sessions/{sid}/finish", scope="calibrate")
    assert refused.status_code == 422, refused.text
    assert refused.json()["type"].endswith("/insufficient-spread")
    moved = api.delete(f"/v1/sessions/{sid}/poses/1", scope="calibrate")
    assert moved.status_code == 200, moved.text
    assert moved.json()["next"] == {"role": "x", "takes": "role"}
    assert _touch(api, sid, role="x", pose=_pose(X_AT)).json()["done"] is True


def test_finishing_before_every_role_says_the_next_touch(api: Api) -> None:
    frame_id, tool_id = _setup(api)
    sid = _session(api, frame_id, tool_id)["id"]
    assert _touch(api, sid, role="origin", pose=_pose(ORIGIN)).status_code == 200
    early = api.post(f"/v1/sessions/{sid}/finish", scope="calibrate")
    assert early.status_code == 422, early.text
    assert "next, touch a point on the frame's +X axis, at least 82 mm" in early.json()["detail"]


def test_a_session_refuses_manual_and_a_pointer_of_another_robot(api: Api) -> None:
    frame_id, _tool = _setup(api)
    other = api.tool(api.robot("r2")["id"], "elsewhere")
    body = {"method": "three_point", "tool_id": other["id"], "format": "kuka_abc"}
    refused = api.post(f"/v1/frames/{frame_id}/sessions", body, scope="calibrate")
    assert refused.status_code == 422, refused.text
    assert refused.json()["errors"][0]["loc"] == ["body", "tool_id"]
    manual = api.post(
        f"/v1/frames/{frame_id}/sessions", {**body, "method": "manual"}, scope="calibrate"
    )
    assert manual.status_code == 422, manual.text
    assert "takes no touches" in manual.json()["detail"]


def test_a_tools_sessions_do_not_list_a_frame_session_of_its_pointer(api: Api) -> None:
    frame_id, tool_id = _setup(api)
    _session(api, frame_id, tool_id)
    assert api.get(f"/v1/tools/{tool_id}/sessions").json()["items"] == []


@pytest.mark.parametrize("protocol", ["kuka_kvp"])
def test_captured_touches_are_the_typed_ones(api: Api, protocol: str) -> None:
    """Each touch read from the controller (the still check of a tool session's capture)
    gives the frame the same poses typed give."""
    with rig(protocol) as r:
        cell = SETUPS[protocol](r)
        pointer = tool_on(api, r)
        api.manual(pointer["id"], POINTER_TCP)
        made = api.post(
            f"/v1/robots/{pointer['robot_id']}/frames", {"name": "fixture-a", "kind": "base"}
        )
        assert made.status_code == 201, made.text
        sid = _session(api, made.json()["id"], pointer["id"])["id"]
        for role, point in (("origin", ORIGIN), ("x", X_AT), ("xy", XY_AT)):
            cell.place(DOWN.as_matrix(), point - DOWN.apply(POINTER_TCP))
            added = _touch(api, sid, role=role, capture=True)
            assert added.status_code == 200, added.text
    state = api.get(f"/v1/sessions/{sid}").json()
    assert [t["source"] for t in state["touches"]] == ["controller"] * 3
    assert all(t["readings"] for t in state["touches"])
    np.testing.assert_allclose(state["estimate"]["position_mm"], ORIGIN, atol=0.01)
