"""Replays the README's first-session walkthrough and checks the values it shows.

The shell blocks between the walkthrough markers are parsed (curl calls, `VAR=$(... | jq -r
.field)` captures, `| jq .field` filters) and sent through the in-process client; each JSON
block after a call must be contained in that call's answer (`jq '.field[n]'` takes one item).

A KUKA simulator plays the robot of the captured calibration: the controller the README
puts (KUKAVARPROXY at 127.0.0.1:7000) is pointed at the simulator's port, and the capture
call, which the README says to repeat at each touch, is sent once per simulated touch with
the simulator's flange moved there first: touches of one fixed point by a torch whose true
TCP is `TRUE_TCP`, while the KRC moves by the data sheet's guess ($TOOL_DATA[3], selected)
in a fixture's $BASE: the TCP the README shows comes out only if each capture takes $TOOL
off $POS_ACT (a $BASE left out moves every flange by one rigid transform, which no TCP from
touches of one point can see; tests/api/test_capture_kuka.py holds each flange for that).
"""

from __future__ import annotations

import json
import re
import shlex
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from testbed.sim.touches import simulate_touches
from tests.api.controller_rigs import Rig, rig
from tests.conftest import Api

README = Path(__file__).resolve().parents[2] / "README.md"
#: The torch's true TCP (mm, flange frame) and the fixed point its tip touches (robot base).
TRUE_TCP = np.array([1.8, -0.6, 151.4])
POINT = np.array([900.0, 150.0, 320.0])
#: The controller the README puts: a KRC's KUKAVARPROXY (replaced by the simulator's port).
README_PORT = '"port": 7000'
CAPTURE = '{"capture": true}'
#: The fixture's base the frame session touches (robot base, mm): its origin, a point on its
#: +X axis and one on its +Y side, each touched with the torch pointing down.
FIXTURE_ORIGIN = np.array([1100.0, -300.0, 250.0])
FIXTURE_TURN = Rotation.from_euler("z", 25, degrees=True)
FIXTURE = {
    "origin": FIXTURE_ORIGIN,
    "x": FIXTURE_ORIGIN + FIXTURE_TURN.apply([400.0, 0.0, 0.0]),
    "xy": FIXTURE_ORIGIN + FIXTURE_TURN.apply([50.0, 300.0, 0.0]),
}
DOWN = Rotation.from_euler("x", 180, degrees=True)


@pytest.fixture
def krc() -> Iterator[Rig]:
    """The KRC of cell 12: the data sheet's torch as tool 3, selected, in a fixture's base."""
    with rig("kuka_kvp") as r:
        r.sim.set_tool(3, 0.0, 0.0, 150.0, 0.0, 0.0, 0.0)
        r.sim.select_tool(3)
        r.sim.set_base(650.0, -220.0, 180.0, 30.0, 0.0, 0.0)
        yield r


def _blocks() -> list[tuple[str, str]]:
    text = README.read_text()
    section = text.split("<!-- walkthrough:start -->")[1].split("<!-- walkthrough:end -->")[0]
    return re.findall(r"```(sh|json)\n(.*?)```", section, flags=re.S)


def _commands(block: str) -> list[str]:
    return [c.strip() for c in block.replace("\\\n", " ").splitlines() if c.strip()]


def _contains(actual: Any, expected: Any) -> None:
    if isinstance(expected, dict):
        assert isinstance(actual, dict), actual
        for key, value in expected.items():
            assert key in actual, f"{key} missing in {actual}"
            _contains(actual[key], value)
    else:
        assert actual == expected, f"{actual!r} != {expected!r}"


def _curl(api: Api, args: list[str], krc: Rig) -> Any:
    method, headers, data, url = "GET", {}, None, None
    it = iter(args[1:])
    for arg in it:
        if arg == "-X":
            method = next(it)
        elif arg == "-H":
            name, _, value = next(it).partition(":")
            headers[name.strip()] = value.strip()
        elif arg == "-d":
            data = next(it)
        elif arg.startswith("http"):
            url = arg
        else:
            assert arg in {"-s", "-i"}, f"unexpected curl argument {arg}"
    assert url is not None
    path = url.removeprefix("http://127.0.0.1:8000")
    if method == "PUT" and path.endswith("/controller"):
        assert data is not None
        assert README_PORT in data, data
        data = data.replace(README_PORT, f'"port": {krc.sim.port}')
    if data == CAPTURE:
        return _capture_each_touch(api, method, path, headers, krc)
    role = json.loads(data).get("role") if data and '"capture": true' in data else None
    if role is not None:  # the torch's tip jogged onto the fixture's point of that role
        krc.sim.set_flange(tuple(FIXTURE[role] - DOWN.apply(TRUE_TCP)), DOWN.as_matrix())
    response = api.client.request(method, path, headers=headers, content=data)
    assert response.status_code < 400, response.text
    return response.json()


def _capture_each_touch(api: Api, method: str, path: str, headers: dict[str, str], krc: Rig) -> Any:
    """The capture as the README says to make it: at each touch, the robot jogged there."""
    touches = simulate_touches(8, seed=12, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    for rotation, flange in zip(touches.R, touches.f, strict=True):
        krc.sim.set_flange(tuple(flange), rotation)
        response = api.client.request(method, path, headers=headers, content=CAPTURE)
        assert response.status_code < 400, response.text
    return response.json()


def test_readme_walkthrough(api: Api, krc: Rig) -> None:
    env = {"URL": "http://127.0.0.1:8000", "KEY": api.keys["admin"]}
    last: Any = None
    calls = 0
    for kind, block in _blocks():
        if kind == "json":
            _contains(last, json.loads(block))
            continue
        for command in _commands(block):
            command = command.removeprefix("export ")
            target = None
            capture = re.fullmatch(r"(\w+)=\$\((.*)\)", command, flags=re.S)
            if capture:
                target, command = capture.group(1), capture.group(2).strip()
            if not command.startswith("curl"):
                # URL= and KEY=$(tcpcal keys create ...): the test uses its own admin key
                assert re.match(r"(URL|KEY)=", command) or target == "KEY", command
                continue
            pipeline = [p.strip() for p in command.split(" | ")]
            words = shlex.split(re.sub(r"\$(\w+)", lambda m: env[m.group(1)], pipeline[0]))
            result = _curl(api, words, krc)
            calls += 1
            for stage in pipeline[1:]:
                field = re.fullmatch(r"jq (?:-r )?'?\.(\w+)(?:\[(\d+)\])?'?", stage)
                assert field, stage
                result = result[field.group(1)]
                if field.group(2) is not None:
                    result = result[int(field.group(2))]
            if target:
                env[target] = result
            last = result
    assert calls >= 6
    listed = api.get(f"/v1/tools/{env['TOOL']}/calibrations").json()["items"]
    captured = next(c for c in listed if c["method"] == "xyz_npoint")
    touches = api.get(f"/v1/calibrations/{captured['id']}").json()["touches"]
    assert [t["source"] for t in touches] == ["controller"] * 8
    assert np.linalg.norm(np.subtract(captured["tcp"]["position_mm"], TRUE_TCP)) <= 0.01
    served = api.get(f"/v1/frames/{env['FRAME']}/frame").json()
    assert np.linalg.norm(np.subtract(served["frame"]["position_mm"], FIXTURE_ORIGIN)) <= 0.01
    turned = Rotation.from_quat(served["frame"]["quaternion"], scalar_first=True)
    assert (turned * FIXTURE_TURN.inv()).magnitude() < np.radians(0.01)
