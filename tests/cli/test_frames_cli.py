"""`tcpcal frames` lists the fleet's frames, or one robot's (issue 47): each with its kind,
its controller number or symbol, its robot, and for an active one its version, its origin
(mm, base frame) and how it was made, read from the frame a controller is served."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from app.cli import cli
from tests.api.frame_versions import add_frame_version
from tests.cli.in_process import cli_as
from tests.conftest import Api


@pytest.fixture
def runner(api: Api, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    return cli_as("read", api, monkeypatch)


def _frame(api: Api, robot_id: str, name: str, **fields: object) -> str:
    made = api.post(f"/v1/robots/{robot_id}/frames", {"name": name, **fields})
    assert made.status_code == 201, made.text
    return str(made.json()["id"])


def test_frames_lists_the_fleet_and_one_robot(api: Api, runner: CliRunner) -> None:
    kuka = api.robot("kr16", vendor="KUKA")
    abb = api.robot("irb6700", vendor="ABB")
    fixture = _frame(api, kuka["id"], "fixture-a", kind="base", slot=2)
    nozzle = _frame(api, kuka["id"], "glue-nozzle", kind="fixed_tool", slot=5)
    wobj = _frame(api, abb["id"], "table", kind="base", controller_symbol="T_ROB1/Cell/wobjTable")
    add_frame_version(fixture, [812.5, -140.25, 402.0])
    activated = api.post(f"/v1/frames/{fixture}/versions/1/activate", scope="calibrate")
    assert activated.is_success, activated.text

    listed = runner.invoke(cli, ["frames"])
    assert listed.exit_code == 0, listed.output
    rows = {
        fid: [cell.strip() for cell in line.split("\u2502")[1:-1]]
        for line in listed.output.splitlines()
        for fid in (fixture, nozzle, wobj)
        if fid in line
    }
    assert set(rows) == {fixture, nozzle, wobj}, listed.output
    assert rows[fixture][:7] == [
        "fixture-a", "base", "2", "kr16", "v1", "812.500 -140.250 402.000", "manual",
    ], rows[fixture]  # fmt: skip
    assert rows[nozzle][:6] == ["glue-nozzle", "fixed_tool", "5", "kr16", "-", "-"]
    assert rows[wobj][:5] == ["table", "base", "T_ROB1/Cell/wobjTable", "irb6700", "-"]

    one = runner.invoke(cli, ["frames", "irb6700"])
    assert one.exit_code == 0, one.output
    assert wobj in one.output, one.output
    assert fixture not in one.output, one.output


def test_frames_of_a_robot_that_is_not_there_exits_5(api: Api, runner: CliRunner) -> None:
    missing = runner.invoke(cli, ["frames", "no-such-robot"])
    assert missing.exit_code == 5, missing.output
    assert "no robot with id or name 'no-such-robot'" in missing.output
