"""`tcpcal calibrate TOOL --guided [--capture]` through typer's runner against the app, and a
KUKA simulator as the robot: Enter captures the pose the KRC stands at, a typed line is
still a typed pose, `d N` drops touch N (numbered from 1 as shown), `f` finishes; a moving
robot is explained and the prompt repeats; a robot without a controller is said so.

The KRC moves by an old guess of the tool ($ACT_TOOL 3) in a shifted, turned $BASE, so a
captured touch is right only if the service composed $BASE * $POS_ACT * inverse($TOOL)."""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from app.cli import cli
from app.cli import guided as client_guided
from testbed.sim.touches import simulate_touches
from tests.api.capture_steps import POINT, TRUE_TCP
from tests.api.capture_steps import krc as krc
from tests.api.controller_rigs import Rig
from tests.cli.test_controller_cli import runner as runner  # the app in process, calibrate key
from tests.conftest import Api

#: A touch line: number, source, the controller's time of reading (none when typed), numbers.
TOUCH_LINE = re.compile(r"^ +(\d+)  (controller|typed) +(\d\d:\d\d:\d\d)? +-?\d", re.MULTILINE)


def _tool(api: Api, r: Rig | None) -> dict[str, Any]:
    robot = api.robot("kr16")
    if r is not None:
        put = api.request(
            "PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=r.controller_body()
        )
        assert put.status_code == 200, put.text
    return api.tool(robot["id"], "torch", slot=3)


def _kuka_abc(rotation: np.ndarray, flange: np.ndarray) -> str:
    """The flange as the pendant shows it: X Y Z A B C, R = Rz(A) Ry(B) Rx(C)."""
    a, b, c = Rotation.from_matrix(rotation).as_euler("ZYX", degrees=True)
    return " ".join(f"{v:.6f}" for v in (*flange, a, b, c))


@dataclass
class Operator:
    """The person at the cell: each answer (a line, and what to do at the robot before it)
    given when the CLI asks, and every prompt it asked with."""

    script: list[tuple[Callable[[], None] | None, str]]
    prompts: list[str] = field(default_factory=list)

    def __call__(self, prompt: str) -> str | None:
        self.prompts.append(prompt)
        if not self.script:
            return None
        before, line = self.script.pop(0)
        if before is not None:
            before()
        return line + "\n"


def test_enter_captures_a_typed_line_is_typed_d_drops_and_f_finishes(
    api: Api, runner: CliRunner, krc: Rig, monkeypatch: pytest.MonkeyPatch
) -> None:
    tool = _tool(api, krc)
    touches = simulate_touches(8, seed=39, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    poses = list(zip(touches.R, touches.f, strict=True))

    def jog(i: int) -> Callable[[], None]:
        return lambda: krc.sim.set_flange(tuple(poses[i][1]), poses[i][0])

    def start_moving() -> None:
        jog(3)()
        krc.sim.moving_per_read = 0.5

    def come_to_rest() -> None:
        krc.sim.moving_per_read = 0.0
        jog(3)()

    missed = poses[6][1] + [6.0, 0.0, 0.0]  # a touch 6 mm off the point, typed by mistake
    script: list[tuple[Callable[[], None] | None, str]] = [
        (jog(0), ""),
        (jog(1), ""),
        (jog(2), ""),
        (start_moving, ""),  # refused: the prompt repeats for touch 4
        (come_to_rest, ""),
        (jog(4), ""),
        (jog(5), ""),
        (None, _kuka_abc(poses[6][0], missed)),  # touch 7, typed
        (None, "d 7"),
        (jog(6), ""),
        (None, _kuka_abc(*poses[7])),  # touch 8 typed off the pendant, exactly
        (None, "f"),
    ]
    operator = Operator(script)
    monkeypatch.setattr(client_guided, "_read_line", operator)
    done = runner.invoke(
        cli,
        ["calibrate", tool["id"], "--guided", "--capture", "--format", "kuka_abc",
         "--activate", "never"],
    )  # fmt: skip
    assert done.exit_code == 0, done.output
    output = done.output

    assert "press Enter to capture each touch from the robot's controller" in output
    assert "the robot is moving: the robot moved" in output
    assert "nothing was kept; let it come to rest at the touch and capture again" in output
    numbers = [int(p.split()[1]) for p in operator.prompts]
    assert numbers == [1, 2, 3, 4, 4, 5, 6, 7, 8, 7, 8, 9], "the refused touch is asked again"
    assert all(p.endswith("(Enter captures)> ") for p in operator.prompts)

    # Each answer lists every touch with its source: the last list is the kept touches.
    answers = output.split("touches: TCP")
    last = [m.groups() for m in TOUCH_LINE.finditer(answers[-2])]
    assert [(n, s) for n, s, _ in last] == [(str(i), "controller") for i in range(1, 8)] + [
        ("8", "typed")
    ]
    assert all(at is not None for _, s, at in last if s == "controller")
    assert all(at is None for _, s, at in last if s == "typed")
    # the typed miss was listed as touch 7 before `d 7` dropped it
    assert any(("7", "typed") in [m.groups()[:2] for m in TOUCH_LINE.finditer(a)] for a in answers)
    miss = rf"^ +7  typed +{missed[0]:.3f} .* \d\.\d{{3}} mm  outlier$"  # its residual
    assert re.search(miss, output, re.MULTILINE), "the typed miss was shown as an outlier"
    assert "next: " in output
    assert "  from touch 1: tilt the tool axis " in output
    assert "accepted: TCP (" in output

    calibration = api.get(f"/v1/tools/{tool['id']}/calibrations").json()["items"][0]
    assert calibration["quality"]["n_poses"] == 8
    assert np.linalg.norm(np.subtract(calibration["tcp"]["position_mm"], TRUE_TCP)) <= 0.01
    detail = api.get(f"/v1/calibrations/{calibration['id']}").json()
    assert [t["source"] for t in detail["touches"]] == ["controller"] * 7 + ["typed"]


def test_capture_on_a_robot_without_a_controller_says_so_and_opens_no_session(
    api: Api, runner: CliRunner
) -> None:
    tool = _tool(api, None)
    refused = runner.invoke(
        cli, ["calibrate", tool["id"], "--guided", "--capture", "--format", "kuka_abc"], input="\n"
    )
    assert refused.exit_code == 4, refused.output
    assert f"robot {tool['robot_id']} has no controller, so --capture has nothing" in " ".join(
        refused.output.split()
    )
    assert api.get(f"/v1/tools/{tool['id']}/sessions").json()["items"] == []
    alone = runner.invoke(cli, ["calibrate", tool["id"], "--capture", "--format", "kuka_abc"])
    assert alone.exit_code == 2, alone.output
    assert "give --guided too" in alone.output


def test_what_is_not_a_touch_is_explained_and_the_session_goes_on(
    api: Api, runner: CliRunner
) -> None:
    """Typed only (stdin through the runner): a line that is not a pose, `d` without a touch
    number or with one not shown, and `f` before four touches each say why and ask again."""
    tool = _tool(api, None)
    touches = simulate_touches(5, seed=7, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    typed = [_kuka_abc(r, f) for r, f in zip(touches.R, touches.f, strict=True)]
    lines = [typed[0], "hello", "d x", "d 9", typed[1], "f", *typed[2:], "d 5", "f"]
    done = runner.invoke(
        cli,
        ["calibrate", tool["id"], "--guided", "--format", "kuka_abc", "--activate", "never"],
        input="\n".join(lines) + "\n",
    )
    assert done.exit_code == 0, done.output
    output = " ".join(done.output.split())
    assert "not a pose: 'hello'" in output
    assert "which touch? 'd N' drops touch N, numbered from 1 as shown" in output
    assert "no touch 9:" in output
    assert "not finished:" in output
    assert "accepted: TCP (" in output
    calibration = api.get(f"/v1/tools/{tool['id']}/calibrations").json()["items"][0]
    assert calibration["quality"]["n_poses"] == 4
    assert (
        np.linalg.norm(np.subtract(calibration["tcp"]["position_mm"], TRUE_TCP)) <= 1e-4
    )  # six decimals typed


def test_a_moving_robot_is_explained_and_the_same_touch_asked_for_again(
    api: Api, runner: CliRunner, krc: Rig
) -> None:
    """Through stdin, as at a terminal: each Enter meets a robot still moving; each refusal
    is explained, the prompt asks for touch 1 again, and `q` leaves the session open, empty."""
    tool = _tool(api, krc)
    krc.sim.moving_per_read = 0.5
    left = runner.invoke(
        cli,
        ["calibrate", tool["id"], "--guided", "--capture", "--format", "kuka_abc"],
        input="\n\nq\n",
    )
    assert left.exit_code == 0, left.output
    assert left.output.count("touch 1 (Enter captures)> ") == 3, left.output
    assert left.output.count("the robot is moving: the robot moved 1.0000 mm") == 2
    sessions = api.get(f"/v1/tools/{tool['id']}/sessions").json()["items"]
    assert [(s["status"], s["n_poses"]) for s in sessions] == [("open", 0)]
    assert f"--guided --session {sessions[0]['id']}" in " ".join(left.output.split())
