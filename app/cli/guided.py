"""`tcpcal calibrate TOOL --guided [--capture]`: a guided session at the cell, one touch a
line of stdin.

Each line is one answer to the server's guidance: a line of numbers is a pose typed as the
pendant shows it; with `--capture` an empty line (Enter) reads the pose from the robot's
controller instead (`{"capture": true}`: the controller computes the flange from its joint
angles, so nothing is copied by hand); `d N` drops touch N (numbered from 1, as shown);
`f` finishes; `q` leaves the session open to continue with `--session`. After each answer
the touches (with where each came from), the estimate and the next suggested touch are
shown. What the server refuses for one touch (a moving robot, an unreachable controller, a
pose that does not read) is explained and the prompt repeats: the session is as it was.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

from app.cli.bodies import Calibration, Pose, Session, TouchSource, flat_pose
from app.cli.http import EXIT_REFUSED, err, fail, out, problem, refused, request, send
from app.jsontypes import JsonObject

if TYPE_CHECKING:
    import httpx

#: The problems one touch may meet that leave the session as it was: the operator fixes the
#: cause at the cell (lets the robot come to rest, types the pose again) and answers again.
_TOUCH_PROBLEMS = {
    "robot-moving": "the robot is moving",
    "no-controller": "no controller",
    "controller-unreachable": "controller unreachable",
    "controller-refused": "controller refused",
}


def guided_session(
    tool_id: str,
    fmt: str,
    units: dict[str, str],
    target: float | None,
    session_id: str | None,
    activate: str,
    note: str | None,
    *,
    capture: bool = False,
) -> Calibration:
    """Touch by touch until `f` (or the end of stdin) finishes the session; the calibration
    it became."""
    if capture:
        _require_controller(tool_id)
    state = _open(tool_id, fmt, units, target, session_id)
    sid = state["id"]
    err.print(_instructions(sid, fmt, capture), highlight=False)
    _print_session(state)
    finish: JsonObject = {"activate": activate, **({"note": note} if note else {})}
    while (line := _read_line(_prompt(state, capture))) is not None:
        command = line.strip().lower()
        if command == "q":
            err.print(f"left open: tcpcal calibrate {tool_id} --guided --session {sid}")
            raise typer.Exit(0)
        if command == "f":
            done = _finish(sid, finish, strict=False)
            if done is not None:
                return done
            continue
        new_state = _answer(sid, line, capture)
        if new_state is not None:
            state = new_state
            _print_session(state)
    # the end of stdin: a script's last line need not be `f`
    result = _finish(sid, finish, strict=True)
    assert result is not None  # strict: a refusal exits
    return result


def _require_controller(tool_id: str) -> None:
    """Exit 4, saying so, when the tool's robot has no controller to capture from (before a
    session is opened, so none is left behind)."""
    robot_id = send("GET", f"/v1/tools/{tool_id}").json()["robot_id"]
    found = request("GET", f"/v1/robots/{robot_id}/controller")
    if _kind(found) == "no-controller":
        fail(
            EXIT_REFUSED,
            f"robot {robot_id} has no controller, so --capture has nothing to read: an admin "
            f"connects it (PUT /v1/robots/{robot_id}/controller), or leave out --capture and "
            "type each pose as the pendant shows it",
        )
    if found.status_code >= 400:
        refused(found)


def _open(
    tool_id: str,
    fmt: str,
    units: dict[str, str],
    target: float | None,
    session_id: str | None,
) -> Session:
    """A new session, or the open one `session_id` names."""
    if session_id is not None:
        resumed: Session = send("GET", f"/v1/sessions/{session_id}").json()
        return resumed
    body: JsonObject = {"method": "xyz_npoint", "format": fmt}
    if units:
        body["units"] = units
    if target is not None:
        body["target_sigma_mm"] = target
    created: Session = send("POST", f"/v1/tools/{tool_id}/sessions", json=body).json()
    return created


def _instructions(sid: str, fmt: str, capture: bool) -> str:
    how = (
        "press Enter to capture each touch from the robot's controller (let the robot come "
        f"to rest first), or type a pose ({fmt}) as the pendant shows it"
        if capture
        else f"type each touch's pose ({fmt}) as shown on the pendant, one line of numbers"
    )
    return (
        f"session {sid}: {how}; 'd N' drops touch N, 'f' finishes, 'q' leaves it open "
        f"(continue with --session {sid})"
    )


def _prompt(state: Session, capture: bool) -> str:
    touch = state["n_poses"] + 1
    return f"touch {touch} (Enter captures)> " if capture else f"touch {touch}> "


def _read_line(prompt: str) -> str | None:
    """The next line of stdin, asked for with `prompt` (on stderr, so that stdout is the
    session's record); None at its end."""
    import sys

    err.print(prompt, end="", highlight=False)
    line = sys.stdin.readline()
    if not line:
        err.print()
        return None
    return line


def _answer(sid: str, line: str, capture: bool) -> Session | None:
    """The session after one line, or None when the line changed nothing (said why)."""
    text = line.strip()
    if not text:
        return _touch(sid, {"capture": True}) if capture else None
    if text.startswith("#"):
        return None
    words = text.lower().split()
    if words[0] == "d":
        return _drop(sid, words[1:])
    try:
        pose: list[float | list[float]] = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        what = "Enter captures, " if capture else ""
        err.print(
            f"[red]not a pose[/]: {text!r}; {what}a line of numbers is a typed pose, 'd N' "
            "drops touch N, 'f' finishes, 'q' leaves the session open",
            highlight=False,
        )
        return None
    return _touch(sid, {"pose": pose})


def _drop(sid: str, args: list[str]) -> Session | None:
    """`d N`: drop touch N, numbered from 1 as shown (the server's index is N - 1)."""
    if len(args) != 1 or not args[0].isdigit() or int(args[0]) < 1:
        err.print("[red]which touch?[/] 'd N' drops touch N, numbered from 1 as shown")
        return None
    response = request("DELETE", f"/v1/sessions/{sid}/poses/{int(args[0]) - 1}")
    if response.status_code in (404, 422):
        err.print(f"[red]no touch {args[0]}[/]: {problem(response).get('detail')}", highlight=False)
        return None
    return _body(response)


def _touch(sid: str, body: JsonObject) -> Session | None:
    """Add one touch, typed or captured; a refused touch is explained, nothing was kept."""
    response = request("POST", f"/v1/sessions/{sid}/poses", json=body)
    kind = _kind(response)
    if kind in _TOUCH_PROBLEMS:
        err.print(
            f"[red]{_TOUCH_PROBLEMS[kind]}[/]: {problem(response).get('detail')}",
            highlight=False,
        )
        return None
    if response.status_code == 422:
        err.print(f"[red]touch refused[/]: {problem(response).get('detail')}", highlight=False)
        return None
    return _body(response)


def _finish(sid: str, body: JsonObject, *, strict: bool) -> Calibration | None:
    """Finish the session; a refusal (too few touches) is explained and, unless `strict`,
    the session goes on (None)."""
    response = request("POST", f"/v1/sessions/{sid}/finish", json=body)
    if not strict and response.status_code in (409, 422):
        err.print(
            f"[red]not finished[/]: {problem(response).get('detail')}; touch more, or 'q'",
            highlight=False,
        )
        return None
    if response.status_code >= 400:
        refused(response)
    result: Calibration = response.json()
    return result


def _body(response: httpx.Response) -> Session:
    if response.status_code >= 400:
        refused(response)
    state: Session = response.json()
    return state


def _kind(response: httpx.Response) -> str:
    """The last word of a problem's type ("robot-moving"); "" for a success."""
    if response.status_code < 400:
        return ""
    return str(problem(response).get("type", "")).rsplit("/", 1)[-1]


def _print_session(state: Session) -> None:
    """The touches with where each came from, the estimate, the server's words and the next
    suggested touch."""
    outliers = set(state["outliers"])
    given = state["residuals_mm"]
    residuals: list[float | None] = [None] * state["n_poses"] if given is None else [*given]
    rows = zip(state["poses"], state["touches"], residuals, strict=True)
    for number, (pose, touch, residual) in enumerate(rows, 1):
        out.print(
            _touch_line(number, pose, touch, residual, number - 1 in outliers), highlight=False
        )
    estimate = state["estimate"]
    if estimate:
        x, y, z = estimate["tcp_mm"]
        sigma = max(estimate["tcp_sigma_mm"])
        out.print(
            f"{state['n_poses']} touches: TCP {x:.3f} {y:.3f} {z:.3f} mm, 1-sigma {sigma:.3f} mm "
            f"(target {state['target_sigma_mm']:g}), rms {estimate['rms_mm']:.3f} mm",
            highlight=False,
        )
    for message in state["messages"]:
        out.print(f"  {message}", highlight=False)
    if state["next_pose"] is not None:
        numbers = " ".join(f"{v:.3f}" for v in flat_pose(state["next_pose"]))
        out.print(f"next: {numbers}", highlight=False)
    if state["next_touch"] is not None:
        words = state["next_touch"]
        out.print(
            f"  from touch 1: tilt the tool axis {words['tilt_deg']:.0f} deg toward "
            f"{words['lean_deg']:.0f} deg (0 = the flange's +x, 90 = +y), spin "
            f"{words['spin_deg']:.0f} deg about it",
            highlight=False,
        )
    if state["done"]:
        err.print("[green]done[/]: type 'f' to store it (or touch more)")


def _touch_line(
    number: int, pose: Pose, touch: TouchSource, residual: float | None, outlier: bool
) -> str:
    """`  3  controller 08:31:02  x y z ...  0.012 mm` (a typed touch has no time, a touch
    before the first estimate no residual)."""
    at = (touch["read_at"] or "")[11:19]
    numbers = " ".join(f"{v:.3f}" for v in flat_pose(pose))
    off = "" if residual is None else f"  {residual:.3f} mm"
    mark = "  outlier" if outlier else ""
    return f"  {number:>2}  {touch['source']:<10} {at:<8}  {numbers}{off}{mark}"
