"""Frames over HTTP (contract v1.4 "Frames"): registered with their controller's number or
symbol checked against the robot's maker, read, changed with If-Match, archived; their
versions activated (reason, force) and rolled back by the one lifecycle; the active frame
served with its ETag and 304; every write in the audit trail under `frame_id`."""

from __future__ import annotations

from typing import Any

import pytest

from tests.api.frame_versions import add_frame_version
from tests.conftest import Api


def _frame(api: Api, robot_id: str, name: str = "fixture-a", **fields: Any) -> dict[str, Any]:
    response = api.post(f"/v1/robots/{robot_id}/frames", {"name": name, "kind": "base", **fields})
    assert response.status_code == 201, response.text
    return dict(response.json())


def test_a_frame_is_registered_read_listed_and_carries_its_etag(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    made = api.post(
        f"/v1/robots/{robot['id']}/frames",
        {"name": "fixture-a", "kind": "base", "slot": 2, "description": "weld fixture A"},
    )
    assert made.status_code == 201, made.text
    frame = made.json()
    assert {k: frame[k] for k in ("robot_id", "name", "kind", "slot", "active_version")} == {
        "robot_id": robot["id"],
        "name": "fixture-a",
        "kind": "base",
        "slot": 2,
        "active_version": None,
    }
    assert frame["tolerance"]["max_change_mm"] == 5.0
    assert made.headers["etag"].startswith('"')
    read = api.get(f"/v1/frames/{frame['id']}")
    assert read.json() == frame
    assert read.headers["etag"] == made.headers["etag"]
    nozzle = _frame(api, robot["id"], "glue-nozzle", kind="fixed_tool", slot=5)
    listed = api.get(f"/v1/robots/{robot['id']}/frames").json()["items"]
    assert [f["id"] for f in listed] == [frame["id"], nozzle["id"]]
    assert [f["kind"] for f in listed] == ["base", "fixed_tool"]


#: The one refusal of a frame number (app.vendors.maker.WireProtocol.frame_problem, the
#: deployment's check too), by its protocol's range and the controller's name for it.
_OUTSIDE = (
    "slot {slot} is outside {low}-{high}, the frame numbers of a {protocol} controller "
    "({name}): give a slot from {low} to {high}"
)


@pytest.mark.parametrize(
    ("vendor", "slot", "refused"),
    [
        ("KUKA", 32, None),
        ("KUKA", 33, ("kuka_kvp", 1, 32, "BASE_DATA[1..32]")),
        ("FANUC", 9, None),
        ("FANUC", 10, ("fanuc_rmi", 1, 9, "UFRAME[1..9]")),
        ("Yaskawa Motoman", 63, None),
        ("Yaskawa Motoman", 0, ("yaskawa_hses", 1, 63, "UFRAME.CND user frame 1..63")),
        ("Universal Robots", 99, None),  # named by values: a slot is kept, not checked
        (None, 500, None),
    ],
)
def test_the_slot_is_checked_against_the_robots_maker(
    api: Api, vendor: str | None, slot: int, refused: tuple[str, int, int, str] | None
) -> None:
    robot = api.robot("r", vendor=vendor)
    response = api.post(
        f"/v1/robots/{robot['id']}/frames", {"name": "f", "kind": "base", "slot": slot}
    )
    if refused is None:
        assert response.status_code == 201, response.text
        return
    assert response.status_code == 422
    problem = response.json()
    assert problem["type"].endswith("/out-of-range")
    assert problem["errors"][0]["loc"] == ["body", "slot"]
    protocol, low, high, name = refused
    outside = _OUTSIDE.format(slot=slot, low=low, high=high, protocol=protocol, name=name)
    assert problem["detail"] == outside


def test_an_abb_frame_is_named_by_its_symbol(api: Api) -> None:
    robot = api.robot("irb", vendor="ABB")
    frame = _frame(api, robot["id"], controller_symbol="T_ROB1/user/wobjFixA")
    assert frame["controller_symbol"] == "T_ROB1/user/wobjFixA"
    bad = api.post(
        f"/v1/robots/{robot['id']}/frames",
        {"name": "g", "kind": "base", "controller_symbol": "wobjFixA"},
    )
    assert bad.status_code == 422
    assert bad.json()["errors"][0]["loc"] == ["body", "controller_symbol"]


def test_name_and_slot_are_unique_among_the_robots_live_frames(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    first = _frame(api, robot["id"], slot=2)
    same_name = api.post(f"/v1/robots/{robot['id']}/frames", {"name": "fixture-a", "kind": "base"})
    assert same_name.status_code == 409
    assert same_name.json()["errors"][0]["loc"] == ["body", "name"]
    assert (
        f"archive the other first (DELETE /v1/frames/{first['id']})" in same_name.json()["detail"]
    )
    same_slot = api.post(
        f"/v1/robots/{robot['id']}/frames", {"name": "b", "kind": "fixed_tool", "slot": 2}
    )
    assert same_slot.status_code == 409
    assert same_slot.json()["errors"][0]["loc"] == ["body", "slot"]
    assert api.delete(f"/v1/frames/{first['id']}").status_code == 204
    _frame(api, robot["id"], slot=2)  # free again once the other is archived


def test_unknown_kind_and_unknown_field_are_422_naming_the_field(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    kind = api.post(f"/v1/robots/{robot['id']}/frames", {"name": "f", "kind": "table"})
    assert kind.status_code == 422
    assert kind.json()["errors"][0]["loc"] == ["body", "kind"]
    extra = api.post(f"/v1/robots/{robot['id']}/frames", {"name": "f", "kind": "base", "x": 1})
    assert extra.status_code == 422
    assert extra.json()["errors"][0]["loc"] == ["body", "x"]
    missing = api.post("/v1/robots/nope/frames", {"name": "f", "kind": "base"})
    assert missing.status_code == 404


def test_patch_honours_if_match_merges_the_tolerance_and_checks_the_slot(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    frame = _frame(api, robot["id"], slot=2)
    etag = api.get(f"/v1/frames/{frame['id']}").headers["etag"]
    changed = api.patch(
        f"/v1/frames/{frame['id']}",
        {"tolerance": {"max_change_mm": 1.5}, "slot": 3},
        headers={"If-Match": etag},
    )
    assert changed.status_code == 200, changed.text
    assert changed.json()["slot"] == 3
    assert changed.json()["tolerance"]["max_change_mm"] == 1.5
    assert changed.json()["tolerance"]["max_rms_mm"] == 0.5  # kept
    assert changed.headers["etag"] != etag
    stale = api.patch(f"/v1/frames/{frame['id']}", {"name": "x"}, headers={"If-Match": etag})
    assert stale.status_code == 412
    outside = api.patch(f"/v1/frames/{frame['id']}", {"slot": 40})
    assert outside.status_code == 422
    assert outside.json()["errors"][0]["loc"] == ["body", "slot"]


def test_archive_stops_serving_and_keeps_the_history(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    frame = _frame(api, robot["id"])
    add_frame_version(frame["id"], [500, 0, 0])
    assert api.post(f"/v1/frames/{frame['id']}/versions/1/activate", scope="calibrate").is_success
    assert api.delete(f"/v1/frames/{frame['id']}").status_code == 204
    for path in ("", "/frame", "/versions"):
        gone = api.get(f"/v1/frames/{frame['id']}{path}")
        assert gone.status_code == 404, path
        assert gone.json()["type"].endswith("/archived"), path
    assert api.get(f"/v1/robots/{robot['id']}/frames").json()["items"] == []


def test_versions_activation_with_reason_force_and_rollback(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    frame = _frame(api, robot["id"], slot=2)
    fid = frame["id"]
    assert add_frame_version(fid, [500, 0, 0]) == 1
    assert add_frame_version(fid, [501, 0, 0]) == 2
    assert add_frame_version(fid, [520, 0, 0], status="out_of_tolerance") == 3
    etag = api.get(f"/v1/frames/{fid}").headers["etag"]
    first = api.post(
        f"/v1/frames/{fid}/versions/1/activate",
        {"reason": "taught on the pendant"},
        scope="calibrate",
        headers={"If-Match": etag},
    )
    assert first.status_code == 200, first.text
    assert first.json()["active_version"] == 1
    assert first.headers["etag"] != etag
    stale = api.post(
        f"/v1/frames/{fid}/versions/2/activate", scope="calibrate", headers={"If-Match": etag}
    )
    assert stale.status_code == 412
    assert api.post(f"/v1/frames/{fid}/versions/2/activate", scope="calibrate").is_success
    held = api.post(f"/v1/frames/{fid}/versions/3/activate", scope="calibrate")
    assert held.status_code == 409
    assert held.json()["type"].endswith("/out-of-tolerance")
    assert "frame fixture-a" in held.json()["detail"]
    no_reason = api.post(
        f"/v1/frames/{fid}/versions/3/activate", {"force": True}, scope="calibrate"
    )
    assert no_reason.status_code == 422
    assert no_reason.json()["errors"][0]["loc"] == ["body", "reason"]
    forced = api.post(
        f"/v1/frames/{fid}/versions/3/activate",
        {"force": True, "reason": "fixture moved, interim"},
        scope="calibrate",
    )
    assert forced.json()["active_version"] == 3
    back = api.post(f"/v1/frames/{fid}/rollback", {"reason": "wrong"}, scope="calibrate")
    assert back.json()["active_version"] == 2
    assert api.post(f"/v1/frames/{fid}/rollback", scope="calibrate").json()["active_version"] == 1
    none_left = api.post(f"/v1/frames/{fid}/rollback", scope="calibrate")
    assert none_left.status_code == 409
    assert none_left.json()["type"].endswith("/nothing-to-roll-back")
    listed = api.get(f"/v1/frames/{fid}/versions").json()
    assert [v["version"] for v in listed["items"]] == [1, 2, 3]
    assert [v["active"] for v in listed["items"]] == [True, False, False]
    assert listed["items"][0]["frame"] == {"position_mm": [500, 0, 0], "quaternion": [1, 0, 0, 0]}
    assert [(a["version"], a["reason"]) for a in listed["activations"]] == [
        (1, "explicit"),
        (2, "explicit"),
        (3, "forced"),
        (2, "rollback"),
        (1, "rollback"),
    ]
    assert listed["activations"][0]["reason_text"] == "taught on the pendant"
    one = api.get(f"/v1/frames/{fid}/versions/3").json()
    assert (one["version"], one["status"], one["source"]) == (3, "out_of_tolerance", "manual")
    assert api.get(f"/v1/frames/{fid}/versions/9").status_code == 404


def test_the_active_frame_is_served_with_its_etag_and_304(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    frame = _frame(api, robot["id"], slot=2)
    fid = frame["id"]
    none = api.get(f"/v1/frames/{fid}/frame")
    assert none.status_code == 404
    assert none.json()["type"].endswith("/no-active-version")
    assert "has no active pose version yet" in none.json()["detail"]
    add_frame_version(fid, [500, 20, 0])
    api.post(f"/v1/frames/{fid}/versions/1/activate", scope="calibrate")
    served = api.get(f"/v1/frames/{fid}/frame")
    assert served.status_code == 200
    assert served.json() == {
        "frame_id": fid,
        "robot_id": robot["id"],
        "frame_name": "fixture-a",
        "slot": 2,
        "version": 1,
        "frame": {"position_mm": [500, 20, 0], "quaternion": [1, 0, 0, 0]},
        "calibrated_at": served.json()["calibrated_at"],
        "method": "manual",
        "controller": None,  # ?format= adds it (tests/api/test_frame_files.py)
        "controller_error": None,
    }
    etag = served.headers["etag"]
    same = api.get(f"/v1/frames/{fid}/frame", headers={"If-None-Match": etag})
    assert (same.status_code, same.headers["etag"]) == (304, etag)
    add_frame_version(fid, [501, 20, 0])
    api.post(f"/v1/frames/{fid}/versions/2/activate", scope="calibrate")
    changed = api.get(f"/v1/frames/{fid}/frame", headers={"If-None-Match": etag})
    assert changed.status_code == 200
    assert changed.json()["version"] == 2
    assert api.get("/v1/frames/nope/frame").status_code == 404
    assert api.get(
        f"/v1/frames/{fid}/frame", headers={"Authorization": "Bearer x"}
    ).status_code == (401)


def test_a_cell_key_sees_and_writes_frames_of_its_cells_only(api: Api) -> None:
    made = api.post("/v1/keys", {"name": "c12", "scope": "admin", "cells": ["cell-12"]})
    assert made.status_code == 201, made.text
    api.keys["c12"] = made.json()["key"]
    mine = _frame(api, api.robot("r12", cell="cell-12")["id"])
    other = _frame(api, api.robot("r7", cell="cell-7")["id"])
    for fid in (mine["id"], other["id"]):
        add_frame_version(fid, [500, 0, 0])
        api.post(f"/v1/frames/{fid}/versions/1/activate", scope="calibrate")
    assert api.get(f"/v1/frames/{mine['id']}", scope="c12").status_code == 200
    assert api.get(f"/v1/frames/{mine['id']}/frame", scope="c12").status_code == 200
    for path in ("", "/frame", "/versions", "/versions/1"):
        hidden = api.get(f"/v1/frames/{other['id']}{path}", scope="c12")
        assert hidden.status_code == 404, path
        assert hidden.json()["type"].endswith("/not-found"), path
    refused = api.post(f"/v1/frames/{other['id']}/versions/1/activate", scope="c12")
    assert refused.status_code == 404
    assert api.delete(f"/v1/frames/{other['id']}", scope="c12").status_code == 404
    assert api.patch(f"/v1/frames/{other['id']}", {"name": "x"}, scope="c12").status_code == 404


def test_every_frame_write_is_in_the_audit_trail_under_its_frame(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    fid = _frame(api, robot["id"], slot=2)["id"]
    api.patch(f"/v1/frames/{fid}", {"description": "moved to bay 3"})
    add_frame_version(fid, [500, 0, 0])
    api.post(f"/v1/frames/{fid}/versions/1/activate", {"reason": "taught"}, scope="calibrate")
    api.delete(f"/v1/frames/{fid}")
    trail = api.get("/v1/audit", scope="admin", params={"frame_id": fid}).json()["items"]
    mine = list(reversed(trail))
    assert [(e["action"], e["resource_type"]) for e in mine] == [
        ("frame.create", "frame"),
        ("frame.update", "frame"),
        ("version.create", "frame"),
        ("version.activate", "frame"),
        ("frame.archive", "frame"),
    ]
    assert all(e["robot_id"] == robot["id"] and e["tool_id"] is None for e in mine)
    assert mine[3]["detail"]["reason"] == "taught"


def test_a_vendor_change_that_would_strand_a_frame_is_refused_naming_it(api: Api) -> None:
    """The robot's frames are held to the new vendor's frame numbers or symbols, by the check
    their registration makes, as its tools' slots are (tests/api/test_slots.py)."""
    robot = api.robot("kr16", vendor="KUKA")
    fixture = _frame(api, robot["id"], "fixture-a", slot=20)
    _frame(api, robot["id"], "fixture-b", slot=3)
    refused = api.patch(f"/v1/robots/{robot['id']}", {"vendor": "FANUC"})
    assert refused.status_code == 422, refused.text
    assert refused.headers["content-type"].startswith("application/problem+json")
    problem = refused.json()
    assert problem["type"].endswith("/out-of-range")
    assert problem["errors"][0]["loc"] == ["body", "vendor"]
    assert f"frame 'fixture-a' ({fixture['id']}, slot 20)" in problem["detail"]
    assert (
        "slot 20 is outside 1-9, the frame numbers of a fanuc_rmi controller" in (problem["detail"])
    )
    assert "PATCH /v1/frames/{frame_id}" in problem["detail"]
    assert "fixture-b" not in problem["detail"]
    assert problem["context"]["frames"] == [fixture["id"]]
    assert api.get(f"/v1/robots/{robot['id']}").json()["vendor"] == "KUKA"
    # Yaskawa numbers user frames 1..63: slot 20 fits there
    assert api.patch(f"/v1/robots/{robot['id']}", {"vendor": "Yaskawa"}).status_code == 200
    # an ABB work object is named by its symbol; the number kept beside it is checked
    # when the robot turns KUKA (BASE_DATA[1..32])
    irb = api.robot("irb", vendor="ABB")
    wobj = _frame(api, irb["id"], "wobj-a", controller_symbol="T_ROB1/user/wobjA", slot=40)
    refused = api.patch(f"/v1/robots/{irb['id']}", {"vendor": "KUKA"})
    assert refused.status_code == 422, refused.text
    assert f"frame 'wobj-a' ({wobj['id']}, slot 40)" in refused.json()["detail"]
    assert "BASE_DATA[1..32]" in refused.json()["detail"]
    etag = api.get(f"/v1/frames/{wobj['id']}").headers["etag"]
    fixed = api.patch(f"/v1/frames/{wobj['id']}", {"slot": 4}, headers={"If-Match": etag})
    assert fixed.status_code == 200, fixed.text
    assert api.patch(f"/v1/robots/{irb['id']}", {"vendor": "KUKA"}).status_code == 200
