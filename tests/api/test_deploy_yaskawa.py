"""Deploying to a Yaskawa controller over HSES (issue 40): the deployment saves TOOL.CND,
replaces the tool's block, loads it back and reads it again, so every other tool of the file
is byte for byte what the controller had; a load the controller refuses (its mode, remote
off, the file in use) is a 502 /controller-refused in its own codes, told in words, with
nothing changed, on the controller or in tcpcal."""

from __future__ import annotations

import pytest

from tests.api.controller_rigs import SLOT, rig
from tests.api.test_deployments import (
    ACTIVE_POSITION,
    ACTIVE_Q,
    NOTHING_WRITTEN,
    PREVIOUS_POSITION,
    PREVIOUS_Q,
    _deploy,
    _deployments,
    _setup,
)
from tests.conftest import Api
from tests.controllers.yaskawa_sim import TOOLS


def _blocks(cnd: bytes) -> dict[int, bytes]:
    starts = [cnd.index(f"//TOOL {n}\r\n".encode()) for n in TOOLS] + [len(cnd)]
    return {n: cnd[starts[n] : starts[n + 1]] for n in TOOLS}


def test_a_deployment_leaves_the_other_63_tools_byte_identical(api: Api) -> None:
    with rig("yaskawa_hses") as r:
        for n in TOOLS:  # an operator's tool file: names, loads, every tool set
            r.sim.set_tool(
                n,
                (n * 1.5, -n / 4, 100.0 + n),
                (n % 7 * 10.0, -(n % 5) * 3.0, n % 11 * 15.0),
                name=f"TOOL {n:02d}",
                mass_kg=0.5 + n / 20,
                cog_mm=(n / 8, 0.0, 40.0 + n),
            )
        before = _blocks(r.sim.tool_cnd())
        ids = _setup(api, r)
        done = _deploy(api, ids["tool"]["id"])
        assert done.status_code == 201, done.text
        assert done.json()["status"] == "verified"
        assert done.json()["scope"] == "stored"  # TOOL.CND: the controller keeps it
        after = _blocks(r.sim.tool_cnd())
        assert r.sim.loads_applied == 1
        assert {n: after[n] for n in TOOLS if n != SLOT} == {
            n: before[n] for n in TOOLS if n != SLOT
        }
        ours = after[SLOT].split(b"\r\n")
        assert ours[:3] == before[SLOT].split(b"\r\n")[:3]  # //TOOL 3, ///CRC, ///NAME TOOL 03
        assert ours[3].startswith(b"12.500,-3.250,187.125,")
        assert (ours[4], ours[5]) == (b"0.000,0.000,80.000", b"2.500")  # the tool's load
        assert ours[6:] == before[SLOT].split(b"\r\n")[6:]  # inertia and the last line kept
        r.assert_holds(ACTIVE_POSITION, ACTIVE_Q)


@pytest.mark.parametrize(
    ("pendant", "words", "remedy"),
    [
        ({"mode": "teach"}, "status 0x1F, added status 0x2080: incorrect mode", "REMOTE"),
        (
            {"remote": False},
            "status 0x1F, added status 0xE2B2: a file was sent or requested while remote is OFF",
            "REMOTE",
        ),
        (
            {"file_busy": True},
            "status 0x1F, added status 0x2090: the file is being accessed by another function",
            "close it there",
        ),
    ],
    ids=["teach-mode", "remote-off", "file-in-use"],
)
def test_a_refused_load_is_502_in_the_controllers_words_with_nothing_changed(
    api: Api, pendant: dict[str, object], words: str, remedy: str
) -> None:
    with rig("yaskawa_hses") as r:
        r.set_behind_back(PREVIOUS_POSITION, PREVIOUS_Q)
        ids = _setup(api, r)
        tool_id = ids["tool"]["id"]
        tool_before = api.get(f"/v1/tools/{tool_id}")
        file_before = r.sim.tool_cnd()
        for key, value in pendant.items():
            setattr(r.sim, key, value)
        refused = _deploy(api, tool_id)
        assert refused.status_code == 502, refused.text
        problem = refused.json()
        assert problem["type"].endswith("/controller-refused")
        assert problem["controller_message"] == words
        assert words in problem["detail"]
        assert remedy in problem["detail"]
        assert problem["deployment_status"] == "not_written"
        assert NOTHING_WRITTEN in problem["detail"]
        assert r.sim.tool_cnd() == file_before
        assert r.sim.loads_applied == 0
        assert api.get(f"/v1/tools/{tool_id}").headers["etag"] == tool_before.headers["etag"]
        [dep] = _deployments(api, tool_id)
        assert dep["status"] == "not_written"
        assert dep["error"]["type"] == "controller-refused"
        row = api.get("/v1/tools", params={"robot_id": ids["robot"]["id"]}).json()["items"][0]
        assert row["controller"] is None or row["controller"]["state"] != "in_sync"
