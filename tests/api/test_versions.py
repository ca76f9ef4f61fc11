"""Manual TCPs become versions 1..n; activation, rollback, ETags, the served TCP."""

from __future__ import annotations

from app.jsontypes import JsonObject
from tests.conftest import Api


def _setup(api: Api) -> tuple[JsonObject, JsonObject]:
    robot = api.robot("kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "torch", slot=3, load={"mass_kg": 2.5, "cog_mm": [0, 0, 80]})
    return robot, tool


def test_manual_creates_versions_in_order_and_activates(api: Api) -> None:
    _, tool = _setup(api)
    first = api.manual(tool["id"], [0, 0, 150])
    second = api.manual(tool["id"], [1, 2, 151], note="after crash")
    assert (first["version"], first["status"], first["active"]) == (1, "accepted", True)
    assert (second["version"], second["active"]) == (2, True)
    versions = api.get(f"/v1/tools/{tool['id']}/versions").json()
    assert [v["version"] for v in versions["items"]] == [1, 2]
    assert [v["active"] for v in versions["items"]] == [False, True]
    assert versions["items"][1]["note"] == "after crash"
    assert versions["items"][1]["created_by"] == "test-calibrate"
    assert [a["version"] for a in versions["activations"]] == [1, 2]
    assert versions["activations"][1]["previous_version"] == 1


def test_activate_never_keeps_previous_and_explicit_activation_rolls_back(api: Api) -> None:
    _, tool = _setup(api)
    api.manual(tool["id"], [0, 0, 150])
    newer = api.manual(tool["id"], [0, 0, 160], activate="never")
    assert (newer["version"], newer["active"]) == (2, False)
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["version"] == 1

    etag = api.get(f"/v1/tools/{tool['id']}").headers["etag"]
    ok = api.post(
        f"/v1/tools/{tool['id']}/versions/2/activate", scope="calibrate", headers={"If-Match": etag}
    )
    assert ok.status_code == 200
    assert ok.json()["active_version"] == 2
    assert ok.headers["etag"] != etag
    stale = api.post(
        f"/v1/tools/{tool['id']}/versions/1/activate", scope="calibrate", headers={"If-Match": etag}
    )
    assert stale.status_code == 412
    assert stale.json()["type"].endswith("/precondition-failed")
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["tcp"]["position_mm"] == [0, 0, 160]
    back = api.post(f"/v1/tools/{tool['id']}/versions/1/activate", scope="calibrate")
    assert back.json()["active_version"] == 1
    history = api.get(f"/v1/tools/{tool['id']}/versions").json()["activations"]
    assert [(a["version"], a["reason"]) for a in history] == [
        (1, "calibration:auto"),
        (2, "explicit"),
        (1, "explicit"),
    ]
    missing = api.post(f"/v1/tools/{tool['id']}/versions/9/activate", scope="calibrate")
    assert missing.status_code == 404


def test_tcp_etag_304_and_change(api: Api) -> None:
    _, tool = _setup(api)
    none = api.get(f"/v1/tools/{tool['id']}/tcp")
    assert none.status_code == 404
    assert none.json()["type"].endswith("/no-active-version")
    api.manual(tool["id"], [0, 0, 150])
    first = api.get(f"/v1/tools/{tool['id']}/tcp")
    body = first.json()
    assert body["version"] == 1
    assert body["slot"] == 3
    assert body["method"] == "manual"
    assert body["tcp"] == {"position_mm": [0, 0, 150], "quaternion": [1, 0, 0, 0]}
    etag = first.headers["etag"]
    assert etag.startswith('"')
    not_modified = api.get(f"/v1/tools/{tool['id']}/tcp", headers={"If-None-Match": etag})
    assert not_modified.status_code == 304
    assert not_modified.headers["etag"] == etag
    api.manual(tool["id"], [0, 0, 151])
    changed = api.get(f"/v1/tools/{tool['id']}/tcp", headers={"If-None-Match": etag})
    assert changed.status_code == 200
    assert changed.json()["version"] == 2


def test_tcp_as_kuka_text(api: Api) -> None:
    _, tool = _setup(api)
    api.manual(tool["id"], [0, 0, 150])
    body = api.get(f"/v1/tools/{tool['id']}/tcp?format=kuka").json()
    controller = body["controller"]
    assert controller["format"] == "kuka"
    assert controller["text"].startswith("$TOOL_DATA[3]={X 0")
    assert controller["values"]["Z"] == 150


def test_manual_pose_entry_as_kuka_abc(api: Api) -> None:
    _, tool = _setup(api)
    response = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        {"method": "manual", "format": "kuka_abc", "poses": [[10, 0, 200, 0, 90, 0]]},
        scope="calibrate",
    )
    assert response.status_code == 201, response.text
    tcp = response.json()["tcp"]
    assert tcp["position_mm"] == [10, 0, 200]
    w, x, y, z = tcp["quaternion"]
    assert abs(w - 2**-0.5) < 1e-12
    assert abs(y - 2**-0.5) < 1e-12
    assert abs(x) < 1e-12
    assert abs(z) < 1e-12


def test_tool_table_lists_active_tcps(api: Api) -> None:
    robot, tool = _setup(api)
    other = api.tool(robot["id"], "gripper", slot=1)
    api.manual(tool["id"], [0, 0, 150])
    table = api.get(f"/v1/robots/{robot['id']}/tool-table?format=kuka").json()
    assert [t["tool_id"] for t in table["items"]] == [tool["id"]]
    assert table["items"][0]["controller"]["text"].startswith("$TOOL_DATA[3]=")
    assert table["without_active_version"] == [other["id"]]


def test_archive_tool_stops_serving_and_keeps_history(api: Api) -> None:
    robot, tool = _setup(api)
    calibration = api.manual(tool["id"], [0, 0, 150])
    assert api.delete(f"/v1/tools/{tool['id']}").status_code == 204
    gone = api.get(f"/v1/tools/{tool['id']}/tcp")
    assert gone.status_code == 404
    assert gone.json()["type"].endswith("/archived")
    assert api.get(f"/v1/robots/{robot['id']}/tools").json()["items"] == []
    # the name and slot are free again; the calibration is kept
    again = api.tool(robot["id"], "torch", slot=3)
    assert again["id"] != tool["id"]
    assert api.get(f"/v1/robots/{robot['id']}/tool-table").json()["items"] == []
    kept = api.get(f"/v1/calibrations/{calibration['id']}").json()
    assert (kept["tool_id"], kept["version"]) == (tool["id"], 1)


def test_a_version_of_an_archived_or_out_of_cell_tool_is_404(api: Api) -> None:
    made = api.post("/v1/keys", {"name": "c12", "scope": "read", "cells": ["cell-12"]})
    assert made.status_code == 201, made.text
    api.keys["c12"] = made.json()["key"]
    other = api.tool(api.robot("r7", cell="cell-7")["id"])["id"]
    api.manual(other, [0, 0, 150])
    assert api.get(f"/v1/tools/{other}/versions/1").status_code == 200
    for number in (1, 9):  # another cell's tool: as if absent, whatever the version
        hidden = api.get(f"/v1/tools/{other}/versions/{number}", scope="c12")
        assert hidden.status_code == 404, hidden.text
        assert hidden.json()["detail"] == f"no tool with id {other}", (number, hidden.json())
    assert api.delete(f"/v1/tools/{other}").status_code == 204
    for number in (1, 9):  # a version it had and one it never had: the tool is archived
        gone = api.get(f"/v1/tools/{other}/versions/{number}")
        assert gone.status_code == 404, gone.text
        assert gone.json()["type"].endswith("/archived"), (number, gone.json())


def test_archive_robot_archives_its_tools(api: Api) -> None:
    robot, tool = _setup(api)
    api.manual(tool["id"], [0, 0, 150])
    assert api.delete(f"/v1/robots/{robot['id']}").status_code == 204
    assert api.get(f"/v1/robots/{robot['id']}").json()["type"].endswith("/archived")
    assert api.get(f"/v1/tools/{tool['id']}").json()["type"].endswith("/archived")
    assert api.get("/v1/robots").json()["items"] == []
    assert api.robot("kr16")["name"] == "kr16"


def test_pagination_walks_every_robot_once(api: Api) -> None:
    names = {f"r{i:02d}" for i in range(7)}
    for name in sorted(names):
        api.robot(name)
    seen: list[str] = []
    cursor = None
    while True:
        query = "/v1/robots?limit=3" + (f"&cursor={cursor}" if cursor else "")
        page = api.get(query).json()
        assert len(page["items"]) <= 3
        seen += [r["name"] for r in page["items"]]
        cursor = page["next_cursor"]
        if cursor is None:
            break
    assert sorted(seen) == sorted(names)
    assert len(seen) == 7


def test_patch_tool_changes_etag_and_honours_if_match(api: Api) -> None:
    _, tool = _setup(api)
    etag = api.get(f"/v1/tools/{tool['id']}").headers["etag"]
    patched = api.patch(
        f"/v1/tools/{tool['id']}", {"tolerance": {"max_rms_mm": 0.2}}, headers={"If-Match": etag}
    )
    assert patched.status_code == 200
    assert patched.json()["tolerance"]["max_rms_mm"] == 0.2
    assert patched.json()["tolerance"]["max_residual_mm"] == 1.0
    stale = api.patch(f"/v1/tools/{tool['id']}", {"serial": "x"}, headers={"If-Match": etag})
    assert stale.status_code == 412


def test_calibration_detail_keeps_request_as_received(api: Api) -> None:
    _, tool = _setup(api)
    created = api.manual(tool["id"], [0, 0, 150], note="from pendant")
    detail = api.get(f"/v1/calibrations/{created['id']}").json()
    assert detail["request"] == {
        "method": "manual",
        "tcp": {"position_mm": [0, 0, 150]},
        "note": "from pendant",
    }
    listed = api.get(f"/v1/tools/{tool['id']}/calibrations").json()["items"]
    assert [c["id"] for c in listed] == [created["id"]]


def test_keys_create_list_revoke(api: Api) -> None:
    created = api.post("/v1/keys", {"name": "cell-12", "scope": "read"})
    assert created.status_code == 201
    key = created.json()
    assert key["key"].startswith("tcpcal_")
    assert key["scope"] == "read"
    listed = api.get("/v1/keys", scope="admin").json()["items"]
    assert "key" not in listed[0]
    assert any(k["id"] == key["id"] for k in listed)
    ok = api.client.get("/v1/robots", headers={"Authorization": f"Bearer {key['key']}"})
    assert ok.status_code == 200
    assert api.delete(f"/v1/keys/{key['id']}").status_code == 204
    revoked = api.client.get("/v1/robots", headers={"Authorization": f"Bearer {key['key']}"})
    assert revoked.status_code == 401


def test_health_ready_metrics(api: Api) -> None:
    assert api.client.get("/health").json() == {"status": "ok"}
    ready = api.client.get("/ready").json()
    assert ready["ready"] is True
    assert ready["revision"] == ready["head"]
    api.get("/v1/robots")
    assert api.client.get("/metrics").status_code == 401  # only /health and /ready are open
    text = api.get("/metrics").text
    assert 'tcpcal_http_requests_total{method="GET",route="/v1/robots",status="200"}' in text


def test_version_numbers_beyond_32_bits_are_422_not_500(api: Api) -> None:
    _, tool = _setup(api)
    for version in (2**31, 2**63, 0):
        response = api.get(f"/v1/tools/{tool['id']}/versions/{version}")
        assert response.status_code == 422
        assert response.json()["errors"][0]["loc"] == ["path", "version"]


def test_patch_of_one_tolerance_field_keeps_the_others(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(
        robot["id"],
        tolerance={"check_mm": 0.2, "max_rms_mm": 0.1},
        load={"mass_kg": 2.0, "cog_mm": [0, 0, 50]},
    )
    patched = api.patch(
        f"/v1/tools/{tool['id']}", {"tolerance": {"max_residual_mm": 2.0}, "load": {"mass_kg": 2.5}}
    ).json()
    assert patched["tolerance"] == {
        "max_rms_mm": 0.1,
        "max_residual_mm": 2.0,
        "touch_noise_mm": None,
        "check_mm": 0.2,
        "max_change_mm": 5.0,  # the v1.1 default
        "max_correction_mm": 2.0,  # the v1.3 default
    }
    assert patched["load"] == {"mass_kg": 2.5, "cog_mm": [0, 0, 50]}


def test_every_cursor_of_the_documented_shape_is_a_position(api: Api) -> None:
    """A cursor is 48 hex digits (creation time and id of the row it follows): any such
    string is answered, so the spec's pattern says exactly what the server accepts."""
    for name in ("a", "b", "c"):
        api.robot(name)
    first = api.get("/v1/robots?limit=2").json()
    assert len(first["next_cursor"]) == 48
    rest = api.get(f"/v1/robots?cursor={first['next_cursor']}").json()
    assert [r["name"] for r in first["items"] + rest["items"]] == ["a", "b", "c"]
    assert len(api.get(f"/v1/robots?cursor={'0' * 48}").json()["items"]) == 3  # before all
    assert api.get(f"/v1/robots?cursor={'f' * 48}").json()["items"] == []  # after all
    old_style = api.get("/v1/robots?cursor=WyIyMDIwLTAxLTAxVDAwOjAwOjAwIiwgIngiXQ")
    assert old_style.status_code == 422
    assert old_style.json()["errors"][0]["loc"] == ["query", "cursor"]


def test_keys_are_paginated(api: Api) -> None:
    first = api.get("/v1/keys?limit=2", scope="admin").json()
    assert len(first["items"]) == 2
    rest = api.get(f"/v1/keys?limit=2&cursor={first['next_cursor']}", scope="admin").json()
    assert [k["name"] for k in first["items"] + rest["items"]] == [
        "test-read",
        "test-calibrate",
        "test-admin",
    ]
    assert rest["next_cursor"] is None


def test_solve_with_unknown_tolerance_field_is_422(api: Api) -> None:
    response = api.post(
        "/v1/solve",
        {"method": "manual", "tcp": {"position_mm": [0, 0, 1]}, "tolerance": {"foo": 1}},
        scope="read",
    )
    assert response.status_code == 422
    assert response.json()["errors"][0]["loc"] == ["body", "tolerance", "foo"]


def test_etag_differs_per_format_and_weak_if_none_match_hits(api: Api) -> None:
    _, tool = _setup(api)
    api.manual(tool["id"], [0, 0, 150])
    as_json = api.get(f"/v1/tools/{tool['id']}/tcp")
    as_kuka = api.get(f"/v1/tools/{tool['id']}/tcp?format=kuka")
    assert as_json.headers["etag"] != as_kuka.headers["etag"]
    # the JSON copy's tag does not validate the KUKA representation
    cross = api.get(
        f"/v1/tools/{tool['id']}/tcp?format=kuka",
        headers={"If-None-Match": as_json.headers["etag"]},
    )
    assert cross.status_code == 200
    assert "controller" in cross.json()
    weak = api.get(
        f"/v1/tools/{tool['id']}/tcp?format=kuka",
        headers={"If-None-Match": "W/" + as_kuka.headers["etag"]},
    )
    assert weak.status_code == 304


def test_malformed_parameters_of_the_hot_read_are_422_naming_them(api: Api) -> None:
    # The hot read checks its parameters itself (app.api.params.RawParam): the same 422 as a
    # declared parameter's, with the parameter named and what to send instead.
    _, tool = _setup(api)
    api.manual(tool["id"], [0, 0, 150])
    path = f"/v1/tools/{tool['id']}/tcp"
    for url, headers, loc in (
        (path, {"If-None-Match": "not-an-etag"}, ["header", "if-none-match"]),
        (path, {"If-None-Match": '"abc", garbage'}, ["header", "if-none-match"]),
        (path, {"Accept": "text/plain," * 100}, ["header", "accept"]),
        (f"{path}?format=KUKA", {}, ["query", "format"]),
        (f"{path}?format=", {}, ["query", "format"]),
        ("/v1/tools/robot%3Bdrop/tcp", {}, ["path", "tool_id"]),
        (f"/v1/tools/{'a' * 65}/tcp", {}, ["path", "tool_id"]),
    ):
        response = api.get(url, headers=headers)
        assert response.status_code == 422, (url, headers)
        problem = response.json()
        assert response.headers["content-type"] == "application/problem+json"
        assert problem["errors"][0]["loc"] == loc
        assert loc[0] in problem["detail"]
    star = api.get(path, headers={"If-None-Match": "*"})
    assert star.status_code == 304


def test_tool_table_reports_a_tool_the_format_cannot_express(api: Api) -> None:
    robot, torch = _setup(api)  # slot 3, with a load
    bare = api.tool(robot["id"], "probe")  # no slot, no load
    api.manual(torch["id"], [0, 0, 150])
    api.manual(bare["id"], [0, 0, 90])
    table = api.get(f"/v1/robots/{robot['id']}/tool-table?format=abb").json()
    by_name = {item["tool_name"]: item for item in table["items"]}
    assert by_name["torch"]["controller"]["text"].startswith("PERS tooldata torch:=")
    assert by_name["torch"]["controller_error"] is None
    assert by_name["probe"]["controller"] is None
    assert by_name["probe"]["controller_error"]["type"].endswith("/missing-load")
    assert by_name["probe"]["tcp"]["position_mm"] == [0, 0, 90]
