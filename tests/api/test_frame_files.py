"""A frame in its controller's words over HTTP (contract v1.4 "Frame touches and methods"):
GET /v1/frames/{id}/frame?format= adds `controller`, Accept: text/plain serves the file the
controller loads (ETag, 304, Content-Disposition), and GET /v1/robots/{id}/frame-table holds
every frame of the robot, as JSON or as one file."""

from __future__ import annotations

from typing import Any

from app.vendors.registry import parse_frame_file
from tests.api.frame_versions import add_frame_version
from tests.conftest import Api

TEXT = {"Accept": "text/plain"}


def _active_frame(api: Api, robot_id: str, name: str, position: list[float], **fields: Any) -> str:
    made = api.post(f"/v1/robots/{robot_id}/frames", {"name": name, "kind": "base", **fields})
    assert made.status_code == 201, made.text
    fid = str(made.json()["id"])
    add_frame_version(fid, position)
    activated = api.post(f"/v1/frames/{fid}/versions/1/activate", scope="calibrate")
    assert activated.status_code == 200, activated.text
    return fid


def test_the_active_frame_in_a_controllers_text(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    fid = _active_frame(api, robot["id"], "fixture-a", [500, 20, -3.5], slot=2)
    plain = api.get(f"/v1/frames/{fid}/frame")
    assert "controller" not in plain.json() or plain.json()["controller"] is None
    served = api.get(f"/v1/frames/{fid}/frame", params={"format": "kuka"})
    assert served.status_code == 200, served.text
    controller = served.json()["controller"]
    assert controller["format"] == "kuka"
    assert controller["text"] == "BASE_DATA[2]={X 500.0,Y 20.0,Z -3.5,A 0.0,B 0.0,C 0.0}"
    assert controller["values"]["type"] == "#BASE"
    assert served.json()["version"] == 1
    assert served.headers["etag"] != plain.headers["etag"]  # another representation
    again = api.get(
        f"/v1/frames/{fid}/frame",
        params={"format": "kuka"},
        headers={"If-None-Match": served.headers["etag"]},
    )
    assert again.status_code == 304


def test_a_fixed_tool_is_served_as_the_controllers_stationary_tool(api: Api) -> None:
    robot = api.robot("irb", vendor="ABB")
    fid = _active_frame(
        api,
        robot["id"],
        "glue-nozzle",
        [900, 0, 400],
        kind="fixed_tool",
        controller_symbol="T_ROB1/user/tGlue",
    )
    served = api.get(f"/v1/frames/{fid}/frame", params={"format": "abb"}).json()["controller"]
    assert served["text"].startswith("PERS tooldata tGlue:=[FALSE,[[900.0,0.0,400.0],")
    file = api.get(f"/v1/frames/{fid}/frame", params={"format": "abb"}, headers=TEXT)
    assert file.status_code == 200, file.text
    assert file.headers["content-type"].startswith("text/plain")
    assert file.headers["content-disposition"] == 'attachment; filename="tcpcal_glue_nozzle.mod"'
    assert "    tGlue.tframe:=[[900.0,0.0,400.0],[1.0,0.0,0.0,0.0]];" in file.text.splitlines()
    assert f"/ui/frames/{fid}" in file.text
    (read,) = parse_frame_file("abb", file.text)
    assert read.fixed_tool is True


def test_the_file_needs_a_format_and_a_frame_the_format_can_name(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    fid = _active_frame(api, robot["id"], "no-number", [1, 2, 3])
    no_format = api.get(f"/v1/frames/{fid}/frame", headers=TEXT)
    assert no_format.status_code == 422
    assert no_format.json()["errors"][0]["loc"] == ["query", "format"]
    no_slot = api.get(f"/v1/frames/{fid}/frame", params={"format": "kuka"})
    assert no_slot.status_code == 422
    assert "set the frame's slot" in no_slot.json()["detail"]


def test_a_robots_frame_table_as_json_and_as_one_file(api: Api) -> None:
    robot = api.robot("m-20", vendor="FANUC")
    first = _active_frame(api, robot["id"], "table-left", [1000, -200, 0], slot=1)
    second = _active_frame(api, robot["id"], "table-right", [1000, 200, 0], slot=3)
    bare = api.post(f"/v1/robots/{robot['id']}/frames", {"name": "later", "kind": "base"})
    table = api.get(f"/v1/robots/{robot['id']}/frame-table", params={"format": "fanuc"})
    assert table.status_code == 200, table.text
    body = table.json()
    assert [item["frame_id"] for item in body["items"]] == [first, second]
    assert body["items"][1]["controller"]["text"].startswith("UFRAME[3]: X 1000.0 Y 200.0")
    assert body["without_active_version"] == [bare.json()["id"]]
    file = api.get(
        f"/v1/robots/{robot['id']}/frame-table", params={"format": "fanuc"}, headers=TEXT
    )
    assert file.status_code == 200, file.text
    assert file.headers["content-disposition"] == 'attachment; filename="TCPUFALL.LS"'
    assert [f.slot for f in parse_frame_file("fanuc", file.text)] == [1, 3]
    assert "later" in file.text  # named: no active version yet


def test_a_table_frame_the_format_cannot_name_carries_its_reason(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    fid = _active_frame(api, robot["id"], "no-number", [1, 2, 3])
    items = api.get(f"/v1/robots/{robot['id']}/frame-table", params={"format": "kuka"}).json()
    (item,) = items["items"]
    assert item["frame_id"] == fid
    assert item["controller"] is None
    assert "set the frame's slot" in item["controller_error"]["detail"]
