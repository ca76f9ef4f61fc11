"""Controller files over HTTP: a tool's file (Accept: text/plain), a robot's tool table as one
file, the header (version, who, when, the server's URL), and the JSON left as it was."""

from __future__ import annotations

import re

import numpy as np
import pytest
from numpy.testing import assert_allclose

from app.config import get_settings
from app.vendors.registry import parse_controller_file
from app.words import CONTROLLER_FORMATS
from tests.conftest import Api

TEXT = {"Accept": "text/plain"}


def _robot_with_tools(api: Api, vendor: str = "KUKA") -> tuple[str, dict[str, str]]:
    robot = api.robot("cell7-r1", vendor=vendor)["id"]
    ids = {}
    for slot, (name, z) in enumerate([("torch", 150.0), ("gripper 🤖", 90.0)], start=1):
        tool = api.tool(robot, name, slot=slot, load={"mass_kg": 2.5, "cog_mm": [0, 0, 80]})
        api.manual(tool["id"], [1.5, -2.0, z])
        ids[name] = tool["id"]
    api.tool(robot, "never calibrated", slot=3)
    return robot, ids


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
def test_a_tools_file_parses_back_to_its_active_tcp(api: Api, fmt: str) -> None:
    _, ids = _robot_with_tools(api)
    response = api.get(f"/v1/tools/{ids['torch']}/tcp?format={fmt}", headers=TEXT)
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/plain")
    assert "attachment; filename=" in response.headers["content-disposition"]
    assert response.text.endswith("\n")
    (parsed,) = parse_controller_file(fmt, response.text)
    assert_allclose(parsed.position_mm, [1.5, -2.0, 150.0], atol=5e-4)
    assert_allclose(abs(parsed.quaternion_wxyz[0]), 1.0, atol=1e-9)
    if fmt != "yaskawa":  # TOOL.CND has no comments: no header (app.vendors.yaskawa.file)
        assert "version 1" in response.text
        assert "by test-calibrate" in response.text
        url = f"http://testserver/ui/tools/{ids['torch']}"
        if fmt == "fanuc":  # remarks hold 32 characters: the URL runs over several
            remarks = re.findall(r"^ +\d+:  !(.*) ;$", response.text, re.MULTILINE)
            assert url in "".join(remarks)
        else:
            assert url in response.text


def test_the_header_takes_the_public_url_setting(api: Api, monkeypatch: pytest.MonkeyPatch) -> None:
    _, ids = _robot_with_tools(api)
    monkeypatch.setenv("TCPCAL_PUBLIC_URL", "https://tcpcal.plant.example/")
    get_settings.cache_clear()
    try:
        text = api.get(f"/v1/tools/{ids['torch']}/tcp?format=abb", headers=TEXT).text
    finally:
        monkeypatch.delenv("TCPCAL_PUBLIC_URL")
        get_settings.cache_clear()
    assert f"! https://tcpcal.plant.example/ui/tools/{ids['torch']}\n" in text
    assert "testserver" not in text


def test_the_json_text_and_its_etag_are_unchanged_by_the_file(api: Api) -> None:
    _, ids = _robot_with_tools(api)
    path = f"/v1/tools/{ids['torch']}/tcp?format=kuka"
    doc = api.get(path).json()
    assert doc["controller"]["text"] == "$TOOL_DATA[1]={X 1.5,Y -2.0,Z 150.0,A 0.0,B 0.0,C 0.0}"
    file = api.get(path, headers=TEXT)
    assert file.headers["etag"] != api.get(path).headers["etag"]
    again = api.get(path, headers={**TEXT, "If-None-Match": file.headers["etag"]})
    assert again.status_code == 304


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
def test_a_robots_tool_table_is_one_file_with_every_tool(api: Api, fmt: str) -> None:
    robot, _ids = _robot_with_tools(api)
    response = api.get(f"/v1/robots/{robot}/tool-table?format={fmt}", headers=TEXT)
    assert response.status_code == 200, response.text
    assert response.text.endswith("\n")
    parsed = parse_controller_file(fmt, response.text)
    calibrated = sorted(
        (p for p in parsed if np.linalg.norm(p.position_mm) > 0),
        key=lambda p: float(p.position_mm[2]),
    )
    positions = [p.position_mm for p in calibrated]
    assert_allclose(positions, [[1.5, -2.0, 90.0], [1.5, -2.0, 150.0]], atol=5e-4)
    # Both tools' 2.5 kg in every format that has a load; FANUC's TP program sets the tool
    # frame (UTOOL[n]) alone. Empty entries, if a file had any, hold no load.
    mass = None if fmt == "fanuc" else 2.5
    assert [p.mass_kg for p in calibrated] == [mass, mass]
    empty = [p for p in parsed if np.linalg.norm(p.position_mm) == 0]
    assert [p.mass_kg for p in empty] == [None] * len(empty)
    if fmt != "yaskawa":  # the tool never calibrated is named, not silently missing
        assert "never calibrated" in response.text
    # the JSON table is still served without Accept: text/plain
    assert len(api.get(f"/v1/robots/{robot}/tool-table").json()["items"]) == 2


def test_a_table_names_the_tools_its_format_cannot_hold(api: Api) -> None:
    robot = api.robot("abb-1", vendor="ABB")["id"]
    held = api.tool(robot, "tGun", load={"mass_kg": 3.0, "cog_mm": [0, 0, 50]})
    bare = api.tool(robot, "tNoLoad")
    api.manual(held["id"], [0, 0, 200])
    api.manual(bare["id"], [0, 0, 100])
    text = api.get(f"/v1/robots/{robot}/tool-table?format=abb", headers=TEXT).text
    assert text.startswith("MODULE tcpcal_tools\n")
    assert text.endswith("ENDMODULE\n")
    assert "PERS tooldata tGun:=" in text
    assert "! left out: tNoLoad: an ABB tooldata needs the tool's mass" in text
    # one tool alone that the format cannot hold is refused, naming what to set
    refused = api.get(f"/v1/tools/{bare['id']}/tcp?format=abb", headers=TEXT)
    assert refused.status_code == 422
    assert refused.json()["errors"][0]["loc"][-1] == "mass_kg"


def test_a_file_needs_a_format_and_a_known_robot(api: Api) -> None:
    robot, _ = _robot_with_tools(api)
    no_format = api.get(f"/v1/robots/{robot}/tool-table", headers=TEXT)
    assert no_format.status_code == 422
    assert no_format.json()["errors"][0]["loc"] == ["query", "format"]
    assert api.get("/v1/robots/nope/tool-table?format=ur", headers=TEXT).status_code == 404
    bad = api.get(f"/v1/robots/{robot}/tool-table?format=staubli", headers=TEXT)
    assert bad.status_code == 422


def test_the_abb_module_names_the_tool_by_its_controller_symbol(api: Api) -> None:
    """The module declares or assigns the persistent the robot's programs move by, SYMBOL of
    "TASK/MODULE/SYMBOL", not a data named after the tool (issue 37)."""
    robot = api.robot("abb-2", vendor="ABB")["id"]
    load = {"mass_kg": 3.0, "cog_mm": [0, 0, 50]}
    tool = api.tool(robot, "welding torch", load=load, controller_symbol="T_ROB1/user/tTorch")
    api.manual(tool["id"], [0, 0, 200])
    for path in (
        f"/v1/tools/{tool['id']}/tcp?format=abb",
        f"/v1/robots/{robot}/tool-table?format=abb",
    ):
        text = api.get(path, headers=TEXT).text
        assert re.search(r"^    tTorch:=\[TRUE,\[\[0\.0,0\.0,200\.0\]", text, re.MULTILINE), text
        assert "welding_torch:=" not in text
        assert [p.name for p in parse_controller_file("abb", text)] == ["tTorch"]
    doc = api.get(f"/v1/tools/{tool['id']}/tcp?format=abb").json()
    assert doc["controller"]["text"].startswith("PERS tooldata tTorch:=[TRUE,")


def test_a_kuka_tool_table_holds_only_the_robots_tools(api: Api) -> None:
    """The 14 tools tcpcal does not manage are not in the file: loading it cannot erase them."""
    robot, _ = _robot_with_tools(api)
    text = api.get(f"/v1/robots/{robot}/tool-table?format=kuka", headers=TEXT).text
    code = [line for line in text.splitlines() if not line.startswith(";")]
    assert sorted(int(n) for n in re.findall(r"^TOOL_DATA\[(\d+)\]=", text, re.M)) == [1, 2]
    assert len(code) == 6, code
    assert "; changes only tool(s) 1, 2:" in text
