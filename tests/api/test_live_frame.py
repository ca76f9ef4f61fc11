"""The frame each robot moves in, read by the reconcile round from the same pose read as its
live tool (issue 48, contract v1.4 "Frames at the controller": KUKA $ACT_BASE and $BASE),
and the version of one of its frames that equals it (app.services.robots.live_frame): a KRC
switched on its pendant to an older BASE_DATA[2] moves in that frame's older version, not
its active one; a base none of its frames' versions equals matches none."""

from __future__ import annotations

from typing import Any

from app.storage.db import session_scope
from app.storage.models import RobotLiveFrame
from tests.api.capture_steps import krc as krc
from tests.api.controller_rigs import Rig
from tests.api.frame_versions import add_frame_version
from tests.conftest import Api

#: BASE_DATA[2] as first taught (v1) and as calibrated since (v2, the active one), mm.
OLD_BASE = [800.0, -140.0, 400.0]
NEW_BASE = [812.5, -140.25, 402.0]


def _live_frame(robot_id: str) -> tuple[bool, int | None, str | None, int | None]:
    with session_scope(write=False) as session:
        row = session.get(RobotLiveFrame, robot_id)
        assert row is not None
        return row.read, row.number, row.frame_id, row.version


def _reconcile(api: Api, robot_id: str) -> dict[str, Any]:
    answer = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    assert answer.status_code == 200, answer.text
    return dict(answer.json())


def test_a_krc_switched_to_an_older_base_moves_in_its_older_version(api: Api, krc: Rig) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    put = api.request(
        "PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=krc.controller_body()
    )
    assert put.status_code == 200, put.text
    api.tool(robot["id"], "torch", **krc.tool_fields)
    made = api.post(
        f"/v1/robots/{robot['id']}/frames", {"name": "fixture-a", "kind": "base", "slot": 2}
    )
    assert made.status_code == 201, made.text
    frame_id = made.json()["id"]
    assert add_frame_version(frame_id, OLD_BASE) == 1
    assert add_frame_version(frame_id, NEW_BASE) == 2
    activated = api.post(f"/v1/frames/{frame_id}/versions/2/activate", scope="calibrate")
    assert activated.status_code == 200, activated.text

    krc.sim.set_base_data(2, *OLD_BASE, 0.0, 0.0, 0.0)  # the pendant: the base as first taught
    krc.sim.select_base(2)
    _reconcile(api, robot["id"])
    assert _live_frame(robot["id"]) == (True, 2, frame_id, 1)  # not 2, the active version

    krc.sim.set_base_data(2, *NEW_BASE, 0.0, 0.0, 0.0)
    _reconcile(api, robot["id"])
    assert _live_frame(robot["id"]) == (True, 2, frame_id, 2)

    krc.sim.set_base(900.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # a program's own $BASE, $ACT_BASE -1
    _reconcile(api, robot["id"])
    assert _live_frame(robot["id"]) == (True, None, None, None)
