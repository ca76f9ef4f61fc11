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

A session's format, units and target are the session's: `--session` continues in them, and
a different one given with it is refused (a pose typed in another format would be read as
another pose). With `--capture` and no `--format`, a new session is typed in the format the
controller's pendant shows (the server says which: its `pose_format`). What the server says
for an API client (an HTTP call to make) is said as the prompt takes it (`d 3`).
"""

from __future__ import annotations

import re
import shlex
from typing import TYPE_CHECKING

import typer
from rich.markup import escape

from app.cli.bodies import (
    Calibration,
    Controller,
    MethodList,
    Pose,
    Session,
    TouchSource,
    flat_pose,
)
from app.cli.http import (
    EXIT_BAD_USE,
    EXIT_REFUSED,
    err,
    fail,
    out,
    problem,
    refused,
    request,
    send,
)
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


def guided_method() -> str:
    """The method a guided session collects touches for, and `tcpcal calibrate`'s default:
    the one GET /v1/methods marks `guided` (the CLI keeps no copy of the server's methods)."""
    listed: MethodList = send("GET", "/v1/methods").json()
    return next(m["name"] for m in listed["items"] if m["guided"])


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
    it became. `fmt` "" takes the session's (`session_id`) or the controller's pendant's
    (`capture`)."""
    controller = _require_controller(tool_id) if capture else None
    if session_id is not None:
        state = _resumed(tool_id, session_id, fmt, units, target)
    else:
        state = _create(tool_id, fmt or _pendant_format(controller), units, target)
    sid, fmt = state["id"], state["format"]
    err.print(_instructions(sid, fmt, capture), highlight=False)
    _print_session(state)
    finish: JsonObject = {"activate": activate, **({"note": note} if note else {})}
    while (line := _read_line(_prompt(state, capture))) is not None:
        command = line.strip().lower()
        if command == "q":
            again = _resume_line(tool_id, sid, capture, activate, note)
            err.print(f"left open: {again}", highlight=False, soft_wrap=True, markup=False)
            raise typer.Exit(0)
        if command == "f":
            done = _finish(state, finish, strict=False)
            if done is not None:
                return done
            continue
        new_state = _answer(state, line, capture)
        if new_state is not None:
            state = new_state
            _print_session(state)
    # the end of stdin: a script's last line need not be `f`
    result = _finish(state, finish, strict=True)
    assert result is not None  # strict: a refusal exits
    return result


def _resume_line(tool_id: str, sid: str, capture: bool, activate: str, note: str | None) -> str:
    """The command that continues the session as this one would have gone on, to paste: its
    format, units and target are the session's, so only how it ends is repeated."""
    words = ["tcpcal", "calibrate", tool_id, "--guided", "--session", sid]
    if capture:
        words.append("--capture")
    if activate != "auto":
        words += ["--activate", activate]
    if note:
        words += ["--note", note]
    return shlex.join(words)


def _require_controller(tool_id: str) -> Controller:
    """The tool's robot's controller; exit 4, saying so, when it has none to capture from
    (before a session is opened, so none is left behind)."""
    robot_id = send("GET", f"/v1/tools/{tool_id}").json()["robot_id"]
    found = request("GET", f"/v1/robots/{robot_id}/controller")
    if _kind(found) == "no-controller":
        fail(
            EXIT_REFUSED,
            f"robot {robot_id} has no controller, so --capture has nothing to read: an admin "
            f"connects it (tcpcal connect {robot_id} --protocol PROTOCOL --host HOST), or "
            "leave out --capture and type each pose as the pendant shows it",
        )
    if found.status_code >= 400:
        refused(found)
    controller: Controller = found.json()
    return controller


def _pendant_format(controller: Controller | None) -> str:
    """The format a new session is typed in when no --format was given: the pendant's of the
    controller captured from, as the server's maker table names it."""
    fmt = None if controller is None else controller.get("pose_format")
    if not fmt:
        fail(EXIT_BAD_USE, "give --format, the pendant's pose format (e.g. kuka_abc)")
    return fmt


def _resumed(
    tool_id: str, session_id: str, fmt: str, units: dict[str, str], target: float | None
) -> Session:
    """The open session `session_id` of the tool; exit 2 when it is another tool's, finished,
    or read in another format, units or target than the ones given (each is the session's,
    set when it was created: a pose typed otherwise would be read as another pose)."""
    state: Session = send("GET", f"/v1/sessions/{session_id}").json()
    sid, own = state["id"], state["format"]
    if state["tool_id"] != tool_id:
        fail(
            EXIT_BAD_USE,
            f"session {sid} is tool {state['tool_id']}'s, not {tool_id}'s: name that tool, or "
            "leave out --session to start a session of this one",
        )
    if state["status"] != "open":
        fail(
            EXIT_BAD_USE,
            f"session {sid} is finished (calibration {state['calibration_id']}): start a new "
            "one: leave out --session",
        )
    if fmt and fmt != own:
        fail(
            EXIT_BAD_USE,
            f"session {sid} reads its poses as {own}, not {fmt}: leave out --format to go on "
            f"in {own} (type each pose as {own}), or leave out --session to start a session "
            f"in {fmt}",
        )
    held = _session_units(state)
    if any(held[name] != value for name, value in units.items()):
        given = ", ".join(f"--{name} {value}" for name, value in units.items())
        fail(
            EXIT_BAD_USE,
            f"session {sid} reads its poses in {held['length']} and {held['angle']}, not "
            f"{given}: leave out --length and --angle to go on in the session's units",
        )
    if target is not None and abs(target - state["target_sigma_mm"]) > 1e-12:
        fail(
            EXIT_BAD_USE,
            f"session {sid} is done at {state['target_sigma_mm']:g} mm, not --target "
            f"{target:g}: leave out --target to go on, or start a new session",
        )
    return state


def _session_units(state: Session) -> dict[str, str]:
    """The length and angle units the session reads its poses in."""
    from app.kinematics.poses import default_units

    default = default_units(state["format"])
    given = state["units"] or {}
    return {
        "length": given.get("length") or default.length,
        "angle": given.get("angle") or default.angle,
    }


def _create(tool_id: str, fmt: str, units: dict[str, str], target: float | None) -> Session:
    """A new session of the tool, typed in `fmt`."""
    body: JsonObject = {"method": guided_method(), "format": fmt}
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


def read_line(prompt: str) -> str | None:
    """The next line of stdin, asked for with `prompt` (another guided command's prompt)."""
    return _read_line(prompt)


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


def _answer(state: Session, line: str, capture: bool) -> Session | None:
    """The session after one line, or None when the line changed nothing (said why)."""
    text = line.strip()
    if not text:
        return _touch(state, {"capture": True}) if capture else None
    if text.startswith("#"):
        return None
    words = text.lower().split()
    if words[0] == "d":
        return _drop(state, words[1:])
    try:
        pose: list[float | list[float]] = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        what = "Enter captures, " if capture else ""
        err.print(
            f"[red]not a pose[/]: {escape(repr(text))}; {what}a line of numbers is a typed "
            "pose, 'd N' drops touch N, 'f' finishes, 'q' leaves the session open",
            highlight=False,
        )
        return None
    # The format it was typed in goes with it: the server refuses it, never reads it as
    # another pose, should it not be the session's.
    return _touch(state, {"pose": pose, "format": state["format"]})


def _drop(state: Session, args: list[str]) -> Session | None:
    """`d N`: drop touch N, numbered from 1 as shown (the server's index is N - 1)."""
    if len(args) != 1 or not args[0].isdigit() or int(args[0]) < 1:
        err.print("[red]which touch?[/] 'd N' drops touch N, numbered from 1 as shown")
        return None
    number, held = int(args[0]), state["n_poses"]
    if number > held:
        shown = "no touches yet" if held == 0 else f"touches 1 to {held}" if held > 1 else "touch 1"
        err.print(f"[red]no touch {number}[/]: the session holds {shown}", highlight=False)
        return None
    response = request("DELETE", f"/v1/sessions/{state['id']}/poses/{number - 1}")
    if response.status_code in (404, 422):
        err.print(f"[red]no touch {number}[/]: {said(response)}", highlight=False)
        return None
    return _body(response)


def _touch(state: Session, body: JsonObject) -> Session | None:
    """Add one touch, typed or captured; a refused touch is explained, nothing was kept."""
    response = request("POST", f"/v1/sessions/{state['id']}/poses", json=body)
    kind = _kind(response)
    if kind in _TOUCH_PROBLEMS:
        err.print(f"[red]{_TOUCH_PROBLEMS[kind]}[/]: {said(response)}", highlight=False)
        return None
    if response.status_code == 422:
        err.print(f"[red]touch refused[/]: {said(response)}", highlight=False)
        return None
    return _body(response)


def _finish(state: Session, body: JsonObject, *, strict: bool) -> Calibration | None:
    """Finish the session; a refusal (too few touches) is explained and, unless `strict`,
    the session goes on (None)."""
    response = request("POST", f"/v1/sessions/{state['id']}/finish", json=body)
    if not strict and response.status_code in (409, 422):
        err.print(
            f"[red]not finished[/]: {said(response)}; touch more, or 'q' leaves it open",
            highlight=False,
        )
        return None
    if response.status_code >= 400:
        refused(response)
    result: Calibration = response.json()
    return result


#: An HTTP call a server's sentence names for an API client, in parentheses: "(POST
#: .../poses)". The prompt's own words say the same here.
_HTTP_CALL = re.compile(r" ?\((?:GET|POST|PUT|PATCH|DELETE) /?[^)]*\)")


def in_prompt_words(sentence: str) -> str:
    """A server's sentence without the HTTP calls it names for an API client, markup-safe."""
    return escape(_HTTP_CALL.sub("", sentence))


def said(response: httpx.Response) -> str:
    """What the server said of a refusal, in the prompt's words."""
    return in_prompt_words(str(problem(response).get("detail")))


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
    for message in _messages(state):
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


def _messages(state: Session) -> list[str]:
    """The server's words on the session, a miss said as the prompt drops it (`d 3`, where
    the server tells an API client the index to DELETE)."""
    residuals = state["residuals_mm"] or []
    misses = {f"touch {i + 1} (index {i}) ": i for i in state["outliers"]}
    said = []
    for message in state["messages"]:
        index = next((i for head, i in misses.items() if message.startswith(head)), None)
        if index is None or index >= len(residuals):
            said.append(in_prompt_words(message))
            continue
        n = index + 1
        said.append(
            f"touch {n} is {residuals[index]:.2f} mm off the others, more than the touch noise "
            f"explains: touch the point again, then drop touch {n} with 'd {n}'"
        )
    return said


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
