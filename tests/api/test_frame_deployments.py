"""Deploy a frame's active version to each controller's simulator that writes frames, read it
back, cut the write around it, and reconcile the frames beside the tools in the same round
(issue 48, contract v1.4 "Frames at the controller"); UR and Yaskawa answer 501
/no-frame-writer with the file to load by hand."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from app.vendors.connector import Frame
from app.vendors.registry import connect
from tests.api.controller_rigs import Rig, rig
from tests.api.controller_rigs import secret_key as secret_key  # autouse: ABB passwords
from tests.api.frame_versions import add_frame_version
from tests.conftest import Api
from tests.controllers.simbase import go_silent
from tests.vendors.test_frame_cuts import CASES, WOBJ

OLD = [0.0, 0.0, 100.0]
NEW = [250.5, -40.25, 312.0]
#: where each protocol's frame lives, as the frame's fields say it
FIELDS: dict[str, dict[str, Any]] = {
    "kuka_kvp": {"slot": 3},
    "fanuc_rmi": {"slot": 4},
    "abb_rws1": {"controller_symbol": WOBJ},
    "abb_rws2": {"controller_symbol": WOBJ},
    "techman": {},
}
CUT_BEFORE = [p for p in CASES if CASES[p].before is not None]


@pytest.fixture(params=sorted(CASES))
def frame_rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    with rig(request.param) as r:
        yield r


def _setup(api: Api, r: Rig, protocol: str | None = None) -> dict[str, Any]:
    """A robot on the rig's controller, its frame at the place the protocol addresses, v1 of
    it active at NEW; the controller holding OLD there (written by the connector)."""
    robot = api.robot()
    put = api.request(
        "PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=r.controller_body()
    )
    assert put.status_code == 200, put.text
    fields = FIELDS.get(protocol or r.protocol, {"slot": 3})
    made = api.post(f"/v1/robots/{robot['id']}/frames", {"name": "table", "kind": "base", **fields})
    assert made.status_code == 201, made.text
    frame = made.json()
    add_frame_version(frame["id"], NEW)
    activated = api.post(f"/v1/frames/{frame['id']}/versions/1/activate", scope="calibrate")
    assert activated.is_success, activated.text
    if r.protocol in CASES:
        _hold(r, OLD[2])
    return {"robot": robot, "frame": frame}


def _hold(r: Rig, z: float) -> None:
    spec = CASES[r.protocol]
    with connect(spec.settings(r.sim, 2.0)) as conn:
        conn.write_frame(spec.target, Frame((OLD[0], OLD[1], z), (1.0, 0.0, 0.0, 0.0)))


def _deploy(api: Api, frame_id: str) -> Any:
    return api.post(f"/v1/frames/{frame_id}/deployments", {}, scope="calibrate")


def _deployments(api: Api, frame_id: str) -> list[dict[str, Any]]:
    listed = api.get(f"/v1/frames/{frame_id}/deployments")
    assert listed.status_code == 200, listed.text
    return list(listed.json()["items"])


def _reconcile(api: Api, robot_id: str) -> dict[str, Any]:
    answer = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read")
    assert answer.status_code == 200, answer.text
    return dict(answer.json())


def test_a_frame_is_deployed_verified_and_the_controller_holds_what_tcpcal_says(
    api: Api, frame_rig: Rig
) -> None:
    r = frame_rig
    ids = _setup(api, r)
    frame_id = ids["frame"]["id"]
    done = _deploy(api, frame_id)
    assert done.status_code == 201, done.text
    dep = done.json()
    assert (dep["frame_id"], dep["status"], dep["version"]) == (frame_id, "verified", 1)
    np.testing.assert_allclose(dep["previous"]["position_mm"], OLD, atol=1e-3)
    np.testing.assert_allclose(dep["read_back"]["position_mm"], NEW, atol=1e-3)
    assert CASES[r.protocol].held_z(r.sim) == pytest.approx(NEW[2], abs=1e-3)
    assert _deployments(api, frame_id) == [dep]
    answer = _reconcile(api, ids["robot"]["id"])
    [seen] = answer["frames"]
    assert (seen["frame_id"], seen["state"], seen["target"]) == (frame_id, "in_sync", dep["target"])
    np.testing.assert_allclose(seen["controller"]["position_mm"], NEW, atol=1e-3)
    assert answer["tools"] == []
    events = api.get("/v1/audit", params={"frame_id": frame_id}, scope="admin").json()["items"]
    assert "frame.deploy" in [e["action"] for e in events]


def test_a_pendant_edit_of_a_frame_is_drifted_in_the_next_round(api: Api, frame_rig: Rig) -> None:
    r = frame_rig
    ids = _setup(api, r)
    assert _deploy(api, ids["frame"]["id"]).status_code == 201
    _hold(r, 180.0)  # behind tcpcal's back
    [seen] = _reconcile(api, ids["robot"]["id"])["frames"]
    assert seen["state"] == "drifted"
    assert seen["controller"]["position_mm"][2] == pytest.approx(180.0, abs=1e-3)


def test_a_frame_write_cut_after_it_is_unverified_until_the_next_round_settles_it(
    api: Api, frame_rig: Rig
) -> None:
    r = frame_rig
    ids = _setup(api, r)
    frame_id = ids["frame"]["id"]
    r.sim.fault = go_silent("after", CASES[r.protocol].write)
    failed = _deploy(api, frame_id)
    assert failed.status_code == 502, failed.text
    assert failed.json()["deployment_status"] == "unverified"
    assert CASES[r.protocol].held_z(r.sim) == pytest.approx(NEW[2], abs=1e-3)
    [dep] = _deployments(api, frame_id)
    assert (dep["status"], dep["settled"]) == ("unverified", None)
    r.sim.stalled = False
    r.sim.fault = None
    [seen] = _reconcile(api, ids["robot"]["id"])["frames"]
    assert seen["state"] == "in_sync"
    [dep] = _deployments(api, frame_id)
    assert dep["settled"]["holds"] == "written"


@pytest.mark.parametrize("protocol", CUT_BEFORE)
def test_a_frame_write_cut_before_it_is_not_written_and_the_old_frame_stays(
    api: Api, protocol: str
) -> None:
    with rig(protocol) as r:
        ids = _setup(api, r)
        frame_id = ids["frame"]["id"]
        r.sim.fault = go_silent("before", CASES[protocol].before)  # type: ignore[arg-type]
        failed = _deploy(api, frame_id)
        assert failed.status_code == 502, failed.text
        assert failed.json()["deployment_status"] == "not_written"
        assert CASES[protocol].held_z(r.sim) == pytest.approx(OLD[2], abs=1e-3)
        r.sim.stalled = False
        r.sim.fault = None
        [seen] = _reconcile(api, ids["robot"]["id"])["frames"]
        assert seen["state"] == "drifted"
        assert _deployments(api, frame_id)[0]["settled"] is None


@pytest.mark.parametrize("protocol", ["ur_rtde", "yaskawa_hses"])
def test_a_controller_no_remote_interface_of_which_writes_frames_is_501_with_the_file(
    api: Api, protocol: str
) -> None:
    with rig(protocol) as r:
        ids = _setup(api, r)
        frame_id = ids["frame"]["id"]
        refused = _deploy(api, frame_id)
        assert refused.status_code == 501, refused.text
        problem = refused.json()
        assert problem["type"].endswith("/no-frame-writer")
        assert problem["file"]
        assert problem["reason"]
        answer = _reconcile(api, ids["robot"]["id"])
        assert answer["frames"] == []
        [left_out] = answer["frames_not_addressable"]
        assert left_out["frame_id"] == frame_id
        assert problem["file"] in left_out["reason"]
        assert answer["state"] != "unreachable"


def test_the_round_reads_tools_and_frames_over_one_connection(api: Api) -> None:
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        api.tool(ids["robot"]["id"], **r.tool_fields)
        before = r.sim.connections_accepted
        answer = _reconcile(api, ids["robot"]["id"])
        assert [t["state"] for t in answer["tools"]] == ["no_active_version"]
        assert [f["state"] for f in answer["frames"]] == ["drifted"]
        assert r.sim.connections_accepted == before + 1


def test_a_removed_controller_takes_its_frames_states_with_it(api: Api) -> None:
    """Without a controller nothing is known of what it holds: the frames' controller states
    went with the tools' (they outlived the controller, and the fleet kept saying in_sync)."""
    with rig("kuka_kvp") as r:
        ids = _setup(api, r)
        assert _deploy(api, ids["frame"]["id"]).status_code == 201
        [seen] = _reconcile(api, ids["robot"]["id"])["frames"]
        assert seen["state"] == "in_sync"
    robot_id = ids["robot"]["id"]
    row = _fleet_row(api, ids["frame"]["id"])
    assert row["controller"] is not None
    assert row["controller"]["state"] == "in_sync"
    gone = api.request("DELETE", f"/v1/robots/{robot_id}/controller", "admin")
    assert gone.status_code == 204, gone.text
    assert _fleet_row(api, ids["frame"]["id"])["controller"] is None


def _fleet_row(api: Api, frame_id: str) -> dict[str, Any]:
    listed = api.get("/v1/frames")
    assert listed.status_code == 200, listed.text
    [row] = [item for item in listed.json()["items"] if item["id"] == frame_id]
    return dict(row)
