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
from tests.api.frame_versions import add_frame_version, base_at_two_versions
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
    frame_id = base_at_two_versions(api, robot["id"], 2, OLD_BASE, NEW_BASE)

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


def _frame_row(api: Api, frame_id: str) -> dict[str, Any]:
    answer = api.get("/v1/frames")
    assert answer.status_code == 200, answer.text
    rows = [row for row in answer.json()["items"] if row["id"] == frame_id]
    assert len(rows) == 1, answer.text
    return dict(rows[0])


def test_the_fleet_flags_a_frame_moved_in_at_an_older_version_or_unknown(
    api: Api, krc: Rig
) -> None:
    """GET /v1/frames says which frame the robot moves in after a reconcile round: an older
    version of this frame is moving_in_stale_frame, a base no version of the robot's frames
    has at this frame's slot moving_in_unknown_frame, its active version neither."""
    robot = api.robot("kr16", vendor="KUKA")
    put = api.request(
        "PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=krc.controller_body()
    )
    assert put.status_code == 200, put.text
    api.tool(robot["id"], "torch", **krc.tool_fields)
    frames = {}
    for name, slot in (("fixture-a", 2), ("fixture-b", 3)):
        made = api.post(
            f"/v1/robots/{robot['id']}/frames", {"name": name, "kind": "base", "slot": slot}
        )
        assert made.status_code == 201, made.text
        frames[slot] = made.json()["id"]
    frame_id, other_id = frames[2], frames[3]
    assert add_frame_version(frame_id, OLD_BASE) == 1
    assert add_frame_version(frame_id, NEW_BASE) == 2
    activated = api.post(f"/v1/frames/{frame_id}/versions/2/activate", scope="calibrate")
    assert activated.status_code == 200, activated.text
    before = _frame_row(api, frame_id)
    assert before["live"]["state"] == "unread", before

    krc.sim.set_base_data(2, *OLD_BASE, 0.0, 0.0, 0.0)
    krc.sim.select_base(2)
    _reconcile(api, robot["id"])
    row = _frame_row(api, frame_id)
    assert "moving_in_stale_frame" in row["attention"], row
    assert row["live"]["state"] == "stale_version", row
    assert row["live"]["version"] == 1, row
    assert row["live"]["number"] == 2, row
    other = _frame_row(api, other_id)
    assert other["live"]["state"] == "other_frame", other
    assert not {"moving_in_stale_frame", "moving_in_unknown_frame"} & set(other["attention"])
    flagged = api.get("/v1/frames", params={"attention": "true"}).json()["items"]
    assert frame_id in [r["id"] for r in flagged]

    krc.sim.set_base_data(2, *NEW_BASE, 0.0, 0.0, 0.0)
    _reconcile(api, robot["id"])
    row = _frame_row(api, frame_id)
    assert row["live"]["state"] == "active", row
    assert not {"moving_in_stale_frame", "moving_in_unknown_frame"} & set(row["attention"])

    krc.sim.set_base_data(2, 950.0, 60.0, 410.0, 0.0, 0.0, 0.0)  # a base no version has
    _reconcile(api, robot["id"])
    row = _frame_row(api, frame_id)
    assert row["live"]["state"] == "unknown", row
    assert "moving_in_unknown_frame" in row["attention"], row
    other = _frame_row(api, other_id)  # base 3 is not the one selected
    assert "moving_in_unknown_frame" not in other["attention"], other
