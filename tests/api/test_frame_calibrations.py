"""Frame calibrations over HTTP (contract v1.4 "Frame touches and methods"): manual and
three_point stored as versions by the lifecycle, graded, activated as `activate` allows,
retry-safe with an Idempotency-Key, the pointer's TCP version recorded, the fiducials kept
and named, each refusal a 422 naming its field."""

from __future__ import annotations

from typing import Any

import pytest

from tests.conftest import Api

#: 180 deg about x: the pointer's TCP [0, 0, 100] points down, each touch 100 mm below.
DOWN = [0.0, 1.0, 0.0, 0.0]


def _cell(api: Api) -> tuple[str, str, str]:
    """(robot, frame, pointer tool with an active TCP [0, 0, 100]) ids."""
    robot = api.robot("kr16", vendor="KUKA")
    frame = api.post(f"/v1/robots/{robot['id']}/frames", {"name": "fixture-a", "kind": "base"})
    assert frame.status_code == 201, frame.text
    pointer = api.tool(robot["id"], "pointer", slot=1)
    api.manual(pointer["id"], [0.0, 0.0, 100.0])
    return robot["id"], frame.json()["id"], pointer["id"]


def _three_point(tool_id: str, **fields: Any) -> dict[str, Any]:
    return {
        "method": "three_point",
        "tool_id": tool_id,
        "format": "xyz_wxyz",
        "touches": [
            {"role": "origin", "pose": [1000.0, -200.0, 680.0, *DOWN]},
            {"role": "x", "pose": [1400.0, -200.0, 680.0, *DOWN]},
            {"role": "xy", "pose": [1100.0, 100.0, 680.0, *DOWN]},
        ],
        "options": {"touch_noise_mm": 0.05},
        **fields,
    }


def _calibrate(api: Api, frame_id: str, body: dict[str, Any], **kw: Any) -> Any:
    return api.post(f"/v1/frames/{frame_id}/calibrations", body, scope="calibrate", **kw)


def test_manual_becomes_version_one_active_and_served(api: Api) -> None:
    _, fid, _ = _cell(api)
    made = _calibrate(
        api, fid, {"method": "manual", "frame": {"position_mm": [1200, -350, 420]}, "note": "cad"}
    )
    assert made.status_code == 201, made.text
    body = made.json()
    assert (body["method"], body["status"], body["version"], body["active"]) == (
        "manual",
        "accepted",
        1,
        True,
    )
    assert body["frame"] == {"position_mm": [1200, -350, 420], "quaternion": [1, 0, 0, 0]}
    assert (body["tool"], body["fiducials"], body["change_from_active_mm"]) == (None, [], None)
    served = api.get(f"/v1/frames/{fid}/frame").json()
    assert (served["version"], served["method"]) == (1, "manual")
    version = api.get(f"/v1/frames/{fid}/versions/1").json()
    assert (version["calibration_id"], version["note"]) == (body["id"], "cad")
    listed = api.get(f"/v1/frames/{fid}/calibrations").json()["items"]
    assert listed == [body]


def test_three_point_records_its_pointer_points_and_fiducials(api: Api) -> None:
    _, fid, tool_id = _cell(api)
    made = _calibrate(api, fid, _three_point(tool_id))
    assert made.status_code == 201, made.text
    body = made.json()
    assert (body["status"], body["version"], body["active"]) == ("accepted", 1, True)
    assert body["frame"]["position_mm"] == pytest.approx([1000.0, -200.0, 580.0], abs=1e-9)
    assert body["points_mm"][1] == pytest.approx([1400.0, -200.0, 580.0], abs=1e-9)
    assert (body["tool"]["tool_id"], body["tool"]["version"]) == (tool_id, 1)
    assert [f["name"] for f in body["fiducials"]] == ["origin", "x", "xy"]
    assert body["fiducials"][1]["nominal_mm"] == pytest.approx([400.0, 0.0, 0.0], abs=1e-9)
    assert "within" in body["summary"]
    kept = api.get(f"/v1/frames/{fid}/fiducials").json()
    assert (kept["calibration_id"], [f["name"] for f in kept["items"]]) == (
        body["id"],
        ["origin", "x", "xy"],
    )
    # a second calibration 3 mm away: its change from the active one is said
    moved = _three_point(tool_id)
    for touch in moved["touches"]:
        touch["pose"][0] += 3.0
    again = _calibrate(api, fid, moved).json()
    assert again["change_from_active_mm"] == pytest.approx(3.0, abs=1e-6)
    assert again["change_from_active_deg"] == pytest.approx(0.0, abs=1e-6)
    assert (again["version"], again["active"]) == (2, True)


def test_a_change_past_max_change_mm_is_stored_not_activated(api: Api) -> None:
    _, fid, tool_id = _cell(api)
    _calibrate(api, fid, _three_point(tool_id))
    far = _three_point(tool_id)
    for touch in far["touches"]:
        touch["pose"][1] += 20.0
    held = _calibrate(api, fid, far).json()
    assert (held["version"], held["active"]) == (2, False)
    assert any("max_change_mm" in w for w in held["warnings"])
    assert api.get(f"/v1/frames/{fid}").json()["active_version"] == 1


def test_the_same_idempotency_key_replays_and_another_body_is_409(api: Api) -> None:
    _, fid, tool_id = _cell(api)
    headers = {"Idempotency-Key": "fix-a-1"}
    first = _calibrate(api, fid, _three_point(tool_id), headers=headers)
    again = _calibrate(api, fid, _three_point(tool_id), headers=headers)
    assert (first.status_code, again.status_code) == (201, 201)
    assert again.headers["idempotent-replayed"] == "true"
    assert again.json() == first.json()
    assert [v["version"] for v in api.get(f"/v1/frames/{fid}/versions").json()["items"]] == [1]
    other = _calibrate(api, fid, _three_point(tool_id, note="other"), headers=headers)
    assert other.status_code == 409


def test_a_pointer_with_no_active_version_is_422_at_tool_id(api: Api) -> None:
    robot_id, fid, _ = _cell(api)
    bare = api.tool(robot_id, "bare", slot=2)
    refused = _calibrate(api, fid, _three_point(bare["id"]))
    assert refused.status_code == 422
    problem = refused.json()
    assert problem["errors"][0]["loc"] == ["body", "tool_id"]
    assert "no active TCP version" in problem["detail"]
    unknown = _calibrate(api, fid, _three_point("nope"))
    assert unknown.status_code == 422
    assert unknown.json()["errors"][0]["loc"] == ["body", "tool_id"]
    no_version = _calibrate(api, fid, _three_point(bare["id"], tcp_version=5))
    assert no_version.json()["errors"][0]["loc"] == ["body", "tcp_version"]
    assert api.get(f"/v1/frames/{fid}/versions").json()["items"] == []  # nothing written


def test_a_named_tcp_version_is_the_one_used(api: Api) -> None:
    _, fid, tool_id = _cell(api)
    api.manual(tool_id, [0.0, 0.0, 110.0])  # v2 active
    made = _calibrate(api, fid, _three_point(tool_id, tcp_version=1)).json()
    assert made["tool"]["version"] == 1
    assert made["frame"]["position_mm"] == pytest.approx([1000.0, -200.0, 580.0], abs=1e-9)


def test_a_missing_role_is_422_naming_the_touches(api: Api) -> None:
    _, fid, tool_id = _cell(api)
    body = _three_point(tool_id)
    body["touches"][2]["role"] = "x"
    refused = _calibrate(api, fid, body)
    assert refused.status_code == 422
    assert refused.json()["errors"][0]["loc"][:2] == ["body", "touches"]


def test_fiducials_are_renamed_by_put_and_audited(api: Api) -> None:
    _, fid, tool_id = _cell(api)
    _calibrate(api, fid, _three_point(tool_id))
    named = api.request(
        "PUT", f"/v1/frames/{fid}/fiducials", "calibrate", json={"names": ["A", "B", "C"]}
    )
    assert named.status_code == 200, named.text
    assert [f["name"] for f in named.json()["items"]] == ["A", "B", "C"]
    swapped = api.request(
        "PUT", f"/v1/frames/{fid}/fiducials", "calibrate", json={"names": ["B", "A", "C"]}
    )
    assert [f["name"] for f in swapped.json()["items"]] == ["B", "A", "C"]
    short = api.request("PUT", f"/v1/frames/{fid}/fiducials", "calibrate", json={"names": ["A"]})
    assert short.status_code == 422
    assert short.json()["errors"][0]["loc"] == ["body", "names"]
    twice = api.request(
        "PUT", f"/v1/frames/{fid}/fiducials", "calibrate", json={"names": ["A", "A", "C"]}
    )
    assert twice.status_code == 422
    trail = api.get("/v1/audit", scope="admin", params={"frame_id": fid}).json()["items"]
    assert [e["action"] for e in trail[:2]] == ["frame.fiducials", "frame.fiducials"]
    assert trail[0]["detail"]["to"] == ["B", "A", "C"]


def test_a_calibration_writes_the_lifecycles_events_under_frame_id(api: Api) -> None:
    _, fid, tool_id = _cell(api)
    made = _calibrate(api, fid, _three_point(tool_id)).json()
    trail = api.get("/v1/audit", scope="admin", params={"frame_id": fid}).json()["items"]
    assert [(e["action"], e["resource_type"], e["version"]) for e in reversed(trail)] == [
        ("frame.create", "frame", None),
        ("version.create", "frame", 1),
        ("version.activate", "frame", 1),
        ("calibration.create", "calibration", 1),
    ]
    assert trail[0]["resource_id"] == made["id"]


def test_a_cell_key_calibrates_frames_of_its_cells_only(api: Api) -> None:
    made = api.post("/v1/keys", {"name": "c12", "scope": "calibrate", "cells": ["cell-12"]})
    api.keys["c12"] = made.json()["key"]
    other = api.robot("r7", cell="cell-7")
    frame = api.post(f"/v1/robots/{other['id']}/frames", {"name": "f", "kind": "base"}).json()
    body = {"method": "manual", "frame": {"position_mm": [0, 0, 0]}}
    refused = api.post(f"/v1/frames/{frame['id']}/calibrations", body, scope="c12")
    assert refused.status_code == 404
    assert api.get(f"/v1/frames/{frame['id']}/calibrations", scope="c12").status_code == 404


def test_frames_are_fleet_rows_beside_tools(api: Api) -> None:
    robot_id, fid, tool_id = _cell(api)
    api.post(f"/v1/robots/{robot_id}/frames", {"name": "glue-nozzle", "kind": "fixed_tool"})
    _calibrate(api, fid, _three_point(tool_id))
    rows = api.get("/v1/frames").json()["items"]
    assert [(r["name"], r["kind"], r["robot_name"]) for r in rows] == [
        ("fixture-a", "base", "kr16"),
        ("glue-nozzle", "fixed_tool", "kr16"),
    ]
    calibrated, bare = rows
    assert (calibrated["active_version"], calibrated["attention"]) == (1, [])
    assert calibrated["last_calibration"]["status"] == "accepted"
    assert calibrated["position_mm"] == pytest.approx([1000.0, -200.0, 580.0], abs=1e-9)
    assert (bare["active_version"], bare["attention"]) == (None, ["no_active_version"])
    needing = api.get("/v1/frames", params={"attention": "true"}).json()["items"]
    assert [r["name"] for r in needing] == ["glue-nozzle"]
    csv = api.get("/v1/frames", headers={"Accept": "text/csv"})
    assert csv.status_code == 200
    assert csv.text.splitlines()[0].startswith("frame_id,frame,kind,slot,robot,cell")
    assert len(csv.text.splitlines()) == 3
    tools = api.get("/v1/tools").json()["items"]
    assert [t["name"] for t in tools] == ["pointer"]  # frames are not tools' rows
