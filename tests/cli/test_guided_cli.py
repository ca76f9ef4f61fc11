"""`tcpcal calibrate TOOL --guided [--capture]` through typer's runner against the app, and a
KUKA simulator as the robot: Enter captures the pose the KRC stands at, a typed line is
still a typed pose, `d N` drops touch N (numbered from 1 as shown), `f` finishes; a moving
robot is explained and the prompt repeats; a robot without a controller is said so.

The KRC moves by an old guess of the tool ($ACT_TOOL 3) in a shifted, turned $BASE, so a
captured touch is right only if the service composed $BASE * $POS_ACT * inverse($TOOL)."""

from __future__ import annotations

import re
import shlex
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from app.cli import cli
from app.cli import guided as client_guided
from app.cli import http as client_http
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


# ---- issue 51: a session's format is the session's; the line printed on q works pasted ------
def _left_open(output: str) -> list[str]:
    """The command `q` printed, as a shell would split it when pasted: it must stand on one
    line of the terminal (at 80 columns), and starts with `tcpcal`."""
    found = re.findall(r"(?:^|> )left open: (tcpcal .*)$", output, re.MULTILINE)  # after q
    assert len(found) == 1, output
    words = shlex.split(found[0])
    assert words[0] == "tcpcal"
    return words[1:]


def test_a_resumed_session_reads_poses_in_its_own_format_and_refuses_another(
    api: Api, runner: CliRunner, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A techman_rxyz session resumed with --format kuka_abc once prompted "(kuka_abc)" and
    stored `887.5 18.251 568.212 0 0 -155` as rx ry rz = 0 0 -155 (issue 51, defect 2): a
    different format on resume is refused, naming both, and nothing is stored."""
    monkeypatch.setattr(client_http.err, "width", 80)  # a terminal's: the q line must not wrap
    tool = _tool(api, None)
    opened = runner.invoke(
        cli, ["calibrate", tool["id"], "--guided", "--format", "techman_rxyz"], input="q\n"
    )
    assert opened.exit_code == 0, opened.output
    [session] = api.get(f"/v1/tools/{tool['id']}/sessions").json()["items"]
    typed = "887.5 18.251 568.212 0 0 -155"

    other = runner.invoke(
        cli,
        ["calibrate", tool["id"], "--guided", "--session", session["id"], "--format", "kuka_abc"],
        input=f"{typed}\nq\n",
    )
    said = " ".join(other.output.split())
    assert other.exit_code == 2, other.output
    assert f"session {session['id']} reads its poses as techman_rxyz, not kuka_abc" in said
    assert "leave out --format to go on in techman_rxyz" in said
    assert api.get(f"/v1/sessions/{session['id']}").json()["n_poses"] == 0
    resume = ["calibrate", tool["id"], "--guided", "--session", session["id"]]
    metres = runner.invoke(cli, [*resume, "--length", "m"], input=f"{typed}\nq\n")
    assert metres.exit_code == 2, metres.output
    assert "reads its poses in mm and deg, not --length m" in " ".join(metres.output.split())
    finer = runner.invoke(cli, [*resume, "--target", "0.001"], input=f"{typed}\nq\n")
    assert finer.exit_code == 2, finer.output
    assert "not --target 0.001: leave out --target" in " ".join(finer.output.split())
    assert api.get(f"/v1/sessions/{session['id']}").json()["n_poses"] == 0

    # The line q printed, pasted: the session's own format, no --format needed.
    resumed = runner.invoke(cli, _left_open(opened.output), input=f"{typed}\nq\n")
    assert resumed.exit_code == 0, resumed.output
    assert "type each touch's pose (techman_rxyz)" in " ".join(resumed.output.split())
    kept = api.get(f"/v1/sessions/{session['id']}").json()
    assert kept["poses"] == [[887.5, 18.251, 568.212, 0.0, 0.0, -155.0]]
    assert kept["format"] == "techman_rxyz"


def test_a_session_of_another_tool_or_finished_is_refused_on_resume(
    api: Api, runner: CliRunner
) -> None:
    """--session names one open session of the tool given: another tool's session is not
    continued under this tool's name, and a finished one is said so before any touch."""
    tool = _tool(api, None)
    other = api.tool(tool["robot_id"], "gun", slot=4)
    sid = api.post(
        f"/v1/tools/{other['id']}/sessions",
        {"method": "xyz_npoint", "format": "kuka_abc"},
        scope="calibrate",
    ).json()["id"]
    resume = ["calibrate", tool["id"], "--guided", "--format", "kuka_abc", "--session"]
    wrong = runner.invoke(cli, [*resume, sid], input="q\n")
    assert wrong.exit_code == 2, wrong.output
    assert f"session {sid} is tool {other['id']}'s, not {tool['id']}'s" in " ".join(
        wrong.output.split()
    )
    touches = simulate_touches(4, seed=5, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    mine = api.post(
        f"/v1/tools/{tool['id']}/sessions",
        {"method": "xyz_npoint", "format": "kuka_abc"},
        scope="calibrate",
    ).json()["id"]
    for r, f in zip(touches.R, touches.f, strict=True):
        pose = [float(v) for v in _kuka_abc(r, f).split()]
        assert api.post(f"/v1/sessions/{mine}/poses", {"pose": pose}, scope="calibrate").is_success
    assert api.post(f"/v1/sessions/{mine}/finish", {"activate": "never"}, scope="calibrate")
    done = runner.invoke(cli, [*resume, mine], input="1 2 3 0 0 0\nq\n")
    assert done.exit_code == 2, done.output
    assert f"session {mine} is finished (calibration " in " ".join(done.output.split())
    assert "start a new one: leave out --session" in " ".join(done.output.split())


def test_q_prints_a_line_that_resumes_the_capture_session_and_capture_needs_no_format(
    api: Api, runner: CliRunner, krc: Rig, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`--guided --capture` without --format takes the pendant's format from the robot's
    controller (GET /v1/robots/{id}/controller `pose_format`: kuka_abc for kuka_kvp); the
    line `q` prints keeps --capture and, pasted, continues the session by Enter (issue 51,
    defect 3: it said "error: give --format", exit 2, and dropped --capture)."""
    monkeypatch.setattr(client_http.err, "width", 80)
    tool = _tool(api, krc)
    first = runner.invoke(cli, ["calibrate", tool["id"], "--guided", "--capture"], input="\nq\n")
    assert first.exit_code == 0, first.output
    said = " ".join(first.output.split())
    assert "or type a pose (kuka_abc) as the pendant shows it" in said
    [session] = api.get(f"/v1/tools/{tool['id']}/sessions").json()["items"]
    assert (session["format"], session["n_poses"]) == ("kuka_abc", 1)

    again = _left_open(first.output)
    assert "--capture" in again
    resumed = runner.invoke(cli, again, input="\nq\n")
    assert resumed.exit_code == 0, resumed.output
    assert resumed.output.count("(Enter captures)> ") == 2, resumed.output
    kept = api.get(f"/v1/sessions/{session['id']}").json()
    assert [t["source"] for t in kept["touches"]] == ["controller", "controller"]


def test_the_guided_prompts_hints_are_its_own_words_not_http_calls(
    api: Api, runner: CliRunner
) -> None:
    """What the prompt says to do is what the prompt takes: `d 3` for a miss, not "DELETE
    /v1/sessions/.../poses/2"; an empty session says it holds no touches (it said "touches 1
    to 0, indices 0 to -1"); finishing too early says to touch more, not "POST .../poses";
    a robot without a controller names `tcpcal connect` (issue 51, defect 9)."""
    tool = _tool(api, None)
    touches = simulate_touches(6, seed=3, touch_noise_mm=0.0, tcp_mm=TRUE_TCP, pivot_mm=POINT)
    flanges = [f + ([0.0, 6.0, 0.0] if i == 2 else 0.0) for i, f in enumerate(touches.f)]
    typed = [_kuka_abc(r, f) for r, f in zip(touches.R, flanges, strict=True)]
    lines = ["d 1", "f", *typed, "d 3", "f"]
    done = runner.invoke(
        cli,
        ["calibrate", tool["id"], "--guided", "--format", "kuka_abc", "--activate", "never"],
        input="\n".join(lines) + "\n",
    )
    assert done.exit_code == 0, done.output
    said = " ".join(done.output.split())
    assert "no touch 1: the session holds no touches yet" in said
    assert (
        "not finished: the session holds 0 touches; at least 4 are needed to calibrate: add "
        "touches before finishing; touch more, or 'q' leaves it open"
    ) in said
    assert re.search(
        r"touch 3 is \d+\.\d\d mm off the others, more than the touch noise explains: touch the "
        r"point again, then drop touch 3 with 'd 3'",
        said,
    ), said
    assert "/v1/" not in said, said
    assert "index" not in said, said
    calibration = api.get(f"/v1/tools/{tool['id']}/calibrations").json()["items"][0]
    assert calibration["quality"]["n_poses"] == 5

    refused = runner.invoke(cli, ["calibrate", tool["id"], "--guided", "--capture"], input="q\n")
    assert refused.exit_code == 4, refused.output
    words = " ".join(refused.output.split())
    assert f"an admin connects it (tcpcal connect {tool['robot_id']} --protocol" in words
    assert "/v1/" not in words
