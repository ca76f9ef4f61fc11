"""`tcpcal check-frame FRAME TOUCHES --pointer TOOL --format F [--correct] [--robot]`: a
frame's re-check after a move (issue 49). TOUCHES is a JSON file of the stored fiducials
touched again, `[{"fiducial": name, "pose": ...}]` (names: GET /v1/frames/{id}/fiducials);
the server finds the shift and, with --correct, corrects the frame (with --robot every frame
and reference point of its robot) within max_correction_mm (POST /v1/frames/{id}/checks, the
one service the MQTT command uses too). With --capture (no TOUCHES) each stored fiducial the
server names next is read from the robot's controller on Enter, through a recheck session
(POST /v1/frames/{id}/sessions, "method": "recheck"), whose finish is that same check. This
module only says the answer and turns its verdict into an exit code, as `tcpcal check` does
(app.cli.recheck).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, NoReturn

import typer

from app.cli.bodies import RobotFrame
from app.cli.client import fleet_robots, resolve_tool
from app.cli.frames import robot_frames
from app.cli.guided import read_line
from app.cli.http import EXIT_BAD_USE, EXIT_NOT_FOUND, err, fail, out, refused, request
from app.cli.recheck import EXIT_CORRECTED, EXIT_IN_TOLERANCE, EXIT_RECALIBRATE
from app.jsontypes import JsonObject
from app.schemas.common import ID_PATTERN

if TYPE_CHECKING:  # the server's workers import app.cli's modules, never httpx
    import httpx

#: The exit code of each verdict (the server's FrameCheck.verdict), those of `tcpcal check`.
VERDICT_EXITS = {
    "within_tolerance": EXIT_IN_TOLERANCE,
    "corrected": EXIT_CORRECTED,
    "needs_recalibration": EXIT_RECALIBRATE,
}
CHECK_FRAME_EXITS = (
    "Exit codes: 0 in tolerance; 1 corrected (the new version is active); 7 needs "
    "recalibration (beyond the frame's max_correction_mm, nothing changed; or past check_mm "
    "without --correct); 4 refused (bad input, a touch far from the fiducial it names), 5 not "
    "found or not allowed, 6 server failed, 2 bad use."
)


def register(cli: typer.Typer) -> None:
    """Add `check-frame` to the `tcpcal` command."""
    cli.command(
        "check-frame", rich_help_panel="Client (talks to a server)", epilog=CHECK_FRAME_EXITS
    )(check_frame)


def resolve_frame(ref: str) -> str:
    """The id of the frame `ref` names: an id, a frame name unique in the fleet, or
    "robot/frame". Exit 5 when none matches, 2 when several do."""
    robot, _, name = ref.rpartition("/")
    if not robot and re.fullmatch(ID_PATTERN, ref):
        found = request("GET", f"/v1/frames/{ref}")
        if found.status_code == 200:
            return ref
        if found.status_code not in (404, 422):
            refused(found)
    rows: list[tuple[str, RobotFrame]] = [
        (owner["name"], frame)
        for owner in fleet_robots()
        if not robot or owner["name"] == robot
        for frame in robot_frames(owner["id"])
        if frame["name"] == name
    ]
    if len(rows) == 1:
        return rows[0][1]["id"]
    if rows:
        listed = ", ".join(f"{r}/{f['name']} ({f['id']})" for r, f in rows)
        fail(EXIT_BAD_USE, f"{len(rows)} frames are named {name!r}: {listed}; name robot/frame")
    fail(EXIT_NOT_FOUND, f"no frame with id or name {ref!r}; tcpcal frames lists them")


def check_frame(
    frame: Annotated[
        str,
        typer.Argument(metavar="FRAME", help="the frame: its id, its name, or robot/frame"),
    ],
    touches_file: Annotated[
        Path | None,
        typer.Argument(
            metavar="TOUCHES",
            help='JSON file: [{"fiducial": name, "pose": ...}, ...] (not with --capture)',
        ),
    ] = None,
    *,
    pointer: Annotated[
        str, typer.Option(help="the pointer tool that touched them (its active TCP is used)")
    ],
    fmt: Annotated[str, typer.Option("--format", help="the poses' format, e.g. kuka_abc")],
    capture: Annotated[
        bool,
        typer.Option(
            "--capture",
            help="read each fiducial the server names next from the robot's controller on "
            "Enter (f finishes after three)",
        ),
    ] = False,
    correct: Annotated[
        bool,
        typer.Option(
            "--correct",
            help="past check_mm and within the frame's max_correction_mm, store the frame the "
            "shift gives as a new version and activate it",
        ),
    ] = False,
    robot: Annotated[
        bool,
        typer.Option(
            "--robot",
            help="the robot itself moved: correct every frame and reference point of it",
        ),
    ] = False,
    reason: Annotated[
        str | None, typer.Option(help="why (e.g. the fixture was unbolted), kept with it")
    ] = None,
    idempotency_key: Annotated[
        str | None, typer.Option(help="retry-safe: the same key replays the first answer")
    ] = None,
) -> NoReturn:
    """Touch a frame's stored fiducials again after a move: how far each moved, and, with
    --correct, the frame corrected within max_correction_mm."""
    if robot and not correct:
        fail(EXIT_BAD_USE, "--robot corrects every frame of the robot: add --correct")
    if (touches_file is None) != capture:
        fail(EXIT_BAD_USE, "give TOUCHES (a file of typed touches) or --capture, one of the two")
    options: JsonObject = {
        "correct": "within_limits" if correct else "never",
        "scope": "robot" if robot else "frame",
    }
    if reason:
        options["reason"] = reason
    tool_id, frame_id = resolve_tool(pointer), resolve_frame(frame)
    headers = {"Idempotency-Key": idempotency_key} if idempotency_key else {}
    if touches_file is None:
        response = _captured(frame_id, tool_id, fmt, options, headers)
    else:
        try:
            touches = json.loads(touches_file.read_text())
        except (OSError, ValueError) as exc:
            fail(EXIT_BAD_USE, f"cannot read the touches from {touches_file}: {exc}")
        body: JsonObject = {"tool_id": tool_id, "format": fmt, "touches": touches, **options}
        response = request("POST", f"/v1/frames/{frame_id}/checks", json=body, headers=headers)
    if response.status_code >= 400:
        refused(response)
    result = response.json()
    out.print(result["summary"], highlight=False, soft_wrap=True, markup=False)
    for deviation in result["deviations"]:
        out.print(f"  {deviation['words']}", highlight=False, soft_wrap=True, markup=False)
    raise typer.Exit(VERDICT_EXITS.get(result["verdict"], EXIT_RECALIBRATE))


def _captured(
    frame_id: str, tool_id: str, fmt: str, options: JsonObject, headers: dict[str, str]
) -> httpx.Response:
    """A recheck session's touches, each fiducial the server names next captured on Enter
    (a refused capture said and asked again), finished as the frame's check."""
    body = {"method": "recheck", "tool_id": tool_id, "format": fmt, "options": options}
    made = request("POST", f"/v1/frames/{frame_id}/sessions", json=body)
    if made.status_code >= 400:
        refused(made)
    state = made.json()
    err.print(
        f"recheck session {state['id']}: press Enter to capture each fiducial from the "
        "robot's controller, f to finish",
        highlight=False,
    )
    while state["next"] is not None:
        name = state["next"]["role"]
        line = read_line(f"fiducial {name!r} (Enter captures)> ")
        if line is None or line.strip() == "f":
            break
        added = request(
            "POST", f"/v1/sessions/{state['id']}/poses", json={"fiducial": name, "capture": True}
        )
        if added.status_code >= 400:
            err.print(added.json().get("detail", added.text), highlight=False, markup=False)
            continue
        state = added.json()
    return request("POST", f"/v1/sessions/{state['id']}/finish", json={}, headers=headers)
