"""The steps every capture test takes against a controller simulator (issue 39): a robot on
the rig's controller with a tool the controller can address, a guided session, its finish;
and the cell they touch in: the tool's true TCP, the point it touches, and a KRC that moves
by an old guess of the tool in a shifted, turned $BASE (so $POS_ACT is neither the flange
nor in the robot's base frame)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from tests.api.controller_rigs import SLOT, Rig, rig
from tests.conftest import Api

TRUE_TCP = np.array([12.5, -7.25, 182.0])
POINT = np.array([850.0, -120.0, 240.0])
#: The tool the controller moves by while the touches are taken: an old guess, turned three
#: ways (X, Y, Z mm and KUKA A, B, C or FANUC W, P, R deg).
OLD_GUESS = (4.0, -2.5, 170.0, 10.0, -5.0, 3.0)
#: The KRC's $BASE: a fixture's frame, shifted and turned three ways.
KRC_BASE = (1200.0, -400.0, 50.0, 25.0, -3.0, 1.5)


@pytest.fixture
def krc() -> Iterator[Rig]:
    """A KUKA simulator moving by OLD_GUESS as $TOOL_DATA[SLOT], selected, in KRC_BASE."""
    with rig("kuka_kvp") as r:
        r.sim.set_tool(SLOT, *OLD_GUESS)
        r.sim.select_tool(SLOT)
        r.sim.set_base(*KRC_BASE)
        yield r


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


def finish_and_type_again(
    api: Api,
    tool_id: str,
    sid: str,
    fmt: str,
    state: dict[str, Any],
    printed: list[dict[str, str]],
) -> None:
    """Finish a session of captured touches (`state`, its last answer; `printed`, what the
    controller printed at each): the TCP within 0.01 mm of TRUE_TCP, the calibration keeps
    each touch's readings and its poses; the same poses typed in a new session are typed
    touches and give the same TCP to 1e-9 mm."""
    captured = finish(api, sid)
    assert np.linalg.norm(np.subtract(captured["tcp"]["position_mm"], TRUE_TCP)) <= 0.01
    detail = api.get(f"/v1/calibrations/{captured['id']}").json()
    assert [t["readings"] for t in detail["touches"]] == printed, "the calibration keeps them"
    assert detail["request"]["poses"] == state["poses"]

    typed = guided_session(api, tool_id, fmt)
    for pose in state["poses"]:
        added = api.post(f"/v1/sessions/{typed}/poses", {"pose": pose}, scope="calibrate")
        assert added.status_code == 200, added.text
    assert [t["source"] for t in added.json()["touches"]] == ["typed"] * len(state["poses"])
    np.testing.assert_allclose(
        finish(api, typed)["tcp"]["position_mm"], captured["tcp"]["position_mm"], atol=1e-9
    )
