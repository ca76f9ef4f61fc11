"""The frames a robot's points are taught in and the tools standing in its cell:
`tcpcal frames [ROBOT]` lists a robot's frames, or the fleet's, each with its active origin;
`tcpcal calibrate-frame FRAME --pointer TOOL [--capture]` teaches one touch by touch.

Talks to the server as the rest of the client does (app.cli.http); the exit codes are the
client's (app.cli.client).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.markup import escape
from rich.table import Table

from app.cli.bodies import (
    ActiveRobotFrame,
    FrameCalibration,
    FrameSession,
    MethodList,
    Page,
    Robot,
    RobotFrame,
)
from app.cli.client import fleet_robots, resolve_robot
from app.cli.guided import in_prompt_words, read_line, said
from app.cli.http import (
    EXIT_BAD_USE,
    EXIT_OUT_OF_TOLERANCE,
    err,
    fail,
    out,
    refused,
    request,
    send,
)
from app.jsontypes import JsonObject

if TYPE_CHECKING:
    import httpx


def register(cli: typer.Typer) -> None:
    """Add the frame commands to the `tcpcal` command."""
    for command in (frames, calibrate_frame):
        cli.command(rich_help_panel="Client (talks to a server)")(command)


def frames(
    robot: Annotated[
        str | None,
        typer.Argument(
            metavar="[ROBOT]", help="only this robot's frames (its id or name); else the fleet's"
        ),
    ] = None,
) -> None:
    """Frames (bases, work objects, user frames) and fixed tools: each with its robot, its
    controller number or symbol, its active version and origin (mm, base frame) and its id."""
    fleet = fleet_robots()
    if robot is not None:
        robot_id = resolve_robot(robot)
        fleet = [r for r in fleet if r["id"] == robot_id]
    table = Table("frame", "kind", "slot", "robot", "active", "origin mm", "method", "calibrated")
    table.add_column("id", no_wrap=True, overflow="ignore", min_width=36)
    for owner in fleet:
        for frame in robot_frames(owner["id"]):
            table.add_row(*_cells(owner, frame))
    out.print(table)


def robot_frames(robot_id: str) -> list[RobotFrame]:
    """Every live frame of the robot (GET /v1/robots/{id}/frames), page after page."""
    rows: list[RobotFrame] = []
    cursor: str | None = None
    while True:
        params: dict[str, str | int] = {"limit": 200, **({"cursor": cursor} if cursor else {})}
        page: Page[RobotFrame] = send("GET", f"/v1/robots/{robot_id}/frames", params=params).json()
        rows += page["items"]
        cursor = page["next_cursor"]
        if cursor is None:
            return rows


def _cells(owner: Robot, frame: RobotFrame) -> list[str]:
    """One frame's cells: the active frame read where there is one."""
    place = frame["controller_symbol"] or ("" if frame["slot"] is None else str(frame["slot"]))
    origin = method = calibrated = "-"
    active = "-"
    if frame["active_version"] is not None:
        served: ActiveRobotFrame = send("GET", f"/v1/frames/{frame['id']}/frame").json()
        active = f"v{served['version']}"
        origin = " ".join(f"{v:.3f}" for v in served["frame"]["position_mm"])
        method, calibrated = served["method"], served["calibrated_at"][:16].replace("T", " ")
    return [
        frame["name"], frame["kind"], place, owner["name"], active, origin, method, calibrated,
        frame["id"],
    ]  # fmt: skip


def calibrate_frame(
    frame_id: Annotated[
        str, typer.Argument(metavar="FRAME", help="the frame's id (tcpcal frames)")
    ],
    pointer: Annotated[
        str, typer.Option("--pointer", help="the tool the touches are made with (its id)")
    ],
    method: Annotated[
        str | None,
        typer.Option(help="a frame method that takes touches (default: GET /v1/methods' first)"),
    ] = None,
    fmt: Annotated[
        str, typer.Option("--format", help="pose format (--capture: default the pendant's)")
    ] = "",
    capture: Annotated[
        bool, typer.Option(help="Enter reads each touch from the robot's controller")
    ] = False,
    nominals: Annotated[
        Path | None,
        typer.Option(
            "--nominals",
            help="fit_points: a file of the points to touch in the frame's coordinates (mm, "
            "from the fixture's drawing or CAD), one a line: 'x y z' or 'name x y z' (commas "
            "or spaces; '#' starts a comment); each touch takes the first point no kept touch "
            "carries",
            dir_okay=False,
        ),
    ] = None,
    activate: Annotated[str, typer.Option(help="auto | always | never")] = "auto",
    note: Annotated[str | None, typer.Option(help="why, for the frame's history")] = None,
) -> None:
    """Teach a frame touch by touch (a guided frame session): the role each touch takes is the
    one the server names next, with how far it must be (fit_points: the next point of
    --nominals); Enter captures (--capture), a line of numbers is a typed pose, 'd N' drops
    touch N, 'f' finishes, 'q' leaves it open. Exit 0 stored and accepted, 3 stored out of
    tolerance, 4 refused, 5 not found."""
    points = None if nominals is None else read_nominals(nominals)
    frame: RobotFrame = send("GET", f"/v1/frames/{frame_id}").json()
    fmt = fmt or _pendant_format(frame)
    method = _session_method(frame, method, points)
    body: JsonObject = {"method": method, "tool_id": pointer, "format": fmt}
    state: FrameSession = send("POST", f"/v1/frames/{frame_id}/sessions", json=body).json()
    how = "Enter captures, " if capture else ""
    err.print(
        f"frame session {state['id']} ({fmt}): {how}a line of numbers is a typed pose, "
        "'d N' drops touch N, 'f' finishes, 'q' leaves it open",
        highlight=False,
    )
    _print_frame_session(state)
    finish: JsonObject = {"activate": activate, **({"note": note} if note else {})}
    while (line := read_line(_prompt(state, points))) is not None:
        command = line.strip().lower()
        if command == "q":
            err.print(f"left open: session {state['id']}", highlight=False)
            raise typer.Exit(0)
        if command == "f":
            response = request("POST", f"/v1/sessions/{state['id']}/finish", json=finish)
            if response.status_code in (409, 422):
                err.print(f"[red]not finished[/]: {said(response)}", highlight=False)
                continue
            _print_frame_calibration(response)
        changed = _frame_answer(state, line, capture, points)
        if changed is not None:
            state = changed
            _print_frame_session(state)
    response = request("POST", f"/v1/sessions/{state['id']}/finish", json=finish)
    _print_frame_calibration(response)


def _pendant_format(frame: RobotFrame) -> str:
    """The pose format of the frame's robot's controller; exit 2 asking for --format."""
    controller = request("GET", f"/v1/robots/{frame['robot_id']}/controller")
    fmt = controller.json().get("pose_format", "") if controller.status_code == 200 else ""
    if not fmt:
        fail(EXIT_BAD_USE, "give --format, the pendant's pose format (e.g. kuka_abc)")
    return str(fmt)


def _session_method(frame: RobotFrame, method: str | None, points: list[Nominal] | None) -> str:
    """The method asked for, else the first of the frame's kind (GET /v1/methods); exit 2
    when its touches carry nominal_mm and --nominals is not given, or the other way round."""
    listed: MethodList = send("GET", "/v1/methods").json()
    if method is None:
        method = next(m["name"] for m in listed["frame_methods"] if frame["kind"] in m["kinds"])
    wants = next((m["touch_fields"] for m in listed["frame_methods"] if m["name"] == method), {})
    if wants.get("nominal_mm") and points is None:
        fail(EXIT_BAD_USE, f"{method} touches carry their point in the frame: give --nominals "
             "FILE, one 'x y z' (mm) a line, in the order you will touch them")  # fmt: skip
    if points is not None and "nominal_mm" not in wants:
        fail(EXIT_BAD_USE, f"{method} touches carry no nominal point: leave out --nominals")
    return method


#: One point of a --nominals file: its name (may be empty) and its coordinates (mm).
Nominal = tuple[str, list[float]]


def read_nominals(path: Path) -> list[Nominal]:
    """The points of a --nominals file, in order; exit 2 naming the line that is not one."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        fail(EXIT_BAD_USE, f"cannot read --nominals {path}: {exc.strerror}")
    points: list[Nominal] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        words = raw.split("#", 1)[0].replace(",", " ").split()
        if not words:
            continue
        name = words.pop(0) if len(words) == 4 else ""
        try:
            xyz = [float(w) for w in words]
        except ValueError:
            xyz = []
        if len(xyz) != 3:
            fail(EXIT_BAD_USE, f"{path} line {number}: {raw.strip()!r} is not 'x y z' or "
                 "'name x y z' (mm)")  # fmt: skip
        points.append((name, xyz))
    if not points:
        fail(EXIT_BAD_USE, f"{path} has no points: one 'x y z' (mm) a line")
    return points


def _next_nominal(state: FrameSession, points: list[Nominal] | None) -> Nominal | None:
    """The first point of --nominals no kept touch carries (a dropped touch frees its own)."""
    if points is None:
        return None
    carried = [t["nominal_mm"] for t in state["touches"] if t["nominal_mm"] is not None]
    for point in points:
        if point[1] in carried:
            carried.remove(point[1])
        else:
            return point
    return None


def _prompt(state: FrameSession, points: list[Nominal] | None) -> str:
    """`touch N> `, with the point of --nominals it takes: `touch 2 (P2 100 0 0 mm)> `."""
    number = state["n_touches"] + 1
    nominal = _next_nominal(state, points)
    if nominal is None:
        return f"touch {number}> "
    name, xyz = nominal
    at = " ".join(f"{v:g}" for v in xyz)
    return f"touch {number} ({name + ' ' if name else ''}{at} mm)> "


def _frame_answer(
    state: FrameSession, line: str, capture: bool, points: list[Nominal] | None = None
) -> FrameSession | None:
    """The session after one line, or None when the line changed nothing (said why)."""
    text = line.strip()
    words = text.lower().split()
    if words[:1] == ["d"] and len(words) == 2 and words[1].isdigit() and int(words[1]) >= 1:
        response = request("DELETE", f"/v1/sessions/{state['id']}/poses/{int(words[1]) - 1}")
    else:
        touch: JsonObject = {}
        if not text:
            if not capture:
                return None
            touch["capture"] = True
        else:
            try:
                touch["pose"] = [float(v) for v in text.replace(",", " ").split()]
            except ValueError:
                err.print(f"[red]not a pose[/]: {escape(repr(text))}", highlight=False)
                return None
        told = state["next"]
        if told is not None and told["role"] is not None:
            touch["role"] = told["role"]
        if points is not None:
            nominal = _next_nominal(state, points)
            if nominal is None:
                err.print("[red]no point left[/]: every point of --nominals has its touch; "
                          "'d N' drops one, 'f' finishes", highlight=False)  # fmt: skip
                return None
            touch["nominal_mm"] = nominal[1]
        response = request("POST", f"/v1/sessions/{state['id']}/poses", json=touch)
    if response.status_code in (404, 409, 422, 502):
        err.print(f"[red]touch refused[/]: {said(response)}", highlight=False)
        return None
    if response.status_code >= 400:
        refused(response)
    changed: FrameSession = response.json()
    return changed


def _print_frame_session(state: FrameSession) -> None:
    """The touches with their role, source and point; the frame so far; the next touch."""
    for touch in state["touches"]:
        point = touch["point_mm"]
        at = " ".join(f"{v:.3f}" for v in point) if point else "-"
        nominal = touch["nominal_mm"]
        what = touch["role"] or ("" if nominal is None else " ".join(f"{v:g}" for v in nominal))
        out.print(
            f"  {touch['index'] + 1:>2}  {what:<8} {touch['source']:<10} {at}", highlight=False
        )
    for message in state["messages"]:
        out.print(f"  {in_prompt_words(message)}", highlight=False)
    if state["done"]:
        err.print("[green]done[/]: type 'f' to store it")


def _print_frame_calibration(response: httpx.Response) -> None:
    """The stored frame, its sigmas and summary; exit 0 accepted, 3 out of tolerance."""
    if response.status_code >= 400:
        refused(response)
    cal: FrameCalibration = response.json()
    x, y, z = cal["frame"]["position_mm"]
    out.print(f"frame v{cal['version']} {cal['status']}: origin {x:.3f} {y:.3f} {z:.3f} mm, "
              f"quaternion {' '.join(f'{q:.6f}' for q in cal['frame']['quaternion'])}",
              highlight=False)  # fmt: skip
    quality = cal["quality"]
    if quality["position_sigma_mm"] and quality["angle_sigma_deg"]:
        ps = " ".join(f"{v:.3f}" for v in quality["position_sigma_mm"])
        ags = " ".join(f"{v:.4f}" for v in quality["angle_sigma_deg"])
        out.print(f"  1-sigma: position {ps} mm, angle {ags} deg", highlight=False)
    out.print(f"  {cal['summary']}", highlight=False)
    if cal["status"] != "accepted":
        raise typer.Exit(EXIT_OUT_OF_TOLERANCE)
    raise typer.Exit(0)
