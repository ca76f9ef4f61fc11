"""The cell PC's client: `tcpcal tools|calibrate|history|activate|rollback|check|export|audit`.

Every command that takes a TOOL accepts its id, its name when no other tool has it, or
"robot/tool"; an ambiguous name lists the matches. Talks to a server over HTTP (TCPCAL_URL,
default http://127.0.0.1:8000; TCPCAL_API_KEY).
Pose files exported from a pendant (CSV rows of numbers, or a JSON list of poses) are read
and checked locally in the given format and units before anything is sent.

Exit codes say what happened, for scripts on the cell PC:
0 done (a calibration accepted, a check within tolerance); 3 done but out of tolerance
(stored, not activated); 4 refused by the server (422/409/412: bad input, a unit or
convention mix-up, a conflict); 5 not found or not allowed (401/403/404); 6 the server could
not be reached or failed; 2 bad use or a pose file that does not read. `check --capture`
(the re-check after a collision, app.cli.recheck) says its verdict instead: 0 in tolerance,
1 corrected, 2 needs recalibration, 3 controller failure.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich import box
from rich.markup import escape
from rich.padding import Padding
from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from app.cli import http as client_http
from app.cli.bodies import (
    AuditEvent,
    Calibration,
    CheckResult,
    FleetTool,
    LastCheck,
    Page,
    Plan,
    Robot,
    Tool,
    VersionList,
    flat_pose,
)
from app.cli.guided import guided_method, guided_session
from app.cli.http import (
    EXIT_BAD_USE,
    EXIT_NOT_FOUND,
    EXIT_OUT_OF_TOLERANCE,
    EXIT_REFUSED,
    Params,
    err,
    fail,
    out,
    problem,
    refused,
    request,
    send,
)
from app.cli.recheck import CHECK_EXITS, recheck
from app.jsontypes import JsonArray, JsonObject
from app.words import CONTROLLER_FORMATS

if TYPE_CHECKING:
    import httpx


def register(cli: typer.Typer) -> None:
    """Add the client's commands to the `tcpcal` command."""
    for command in (tools, plan, calibrate, history, activate, rollback, check, export, audit):
        epilog = CHECK_EXITS if command is check else None
        cli.command(rich_help_panel="Client (talks to a server)", epilog=epilog)(command)


# ---- which tool ---------------------------------------------------------------------------
ToolArg = Annotated[
    str,
    typer.Argument(
        metavar="TOOL",
        help="the tool: its id, its name when only one tool has it, or robot/tool "
        "(tcpcal tools lists them)",
    ),
]
_ID = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


def resolve_tool(ref: str) -> str:
    """The id of the tool `ref` names: an id, a tool name unique in the fleet, or
    "robot/tool". Exit 5 when none matches, 2 (listing robot/tool and id of each) when
    several do."""
    robot, _, name = ref.rpartition("/")
    if not robot and _ID.match(ref):
        found = request("GET", f"/v1/tools/{ref}")
        if found.status_code == 200:
            return ref
        if found.status_code not in (404, 422):
            refused(found)
    rows = [
        row
        for row in _fleet_rows({"q": name})
        if row["name"] == name and (not robot or row["robot_name"] == robot)
    ]
    if len(rows) == 1:
        return rows[0]["id"]
    if not rows:
        fail(EXIT_NOT_FOUND, f"no tool with id or name {ref!r}; tcpcal tools lists them")
    listed = "\n".join(f"  {r['robot_name']}/{r['name']}  {r['id']}" for r in rows)
    fail(
        EXIT_BAD_USE,
        f"{len(rows)} tools are named {name!r}; name one as robot/tool or by its id:\n{listed}",
    )


RobotArg = Annotated[
    str,
    typer.Argument(metavar="ROBOT", help="the robot: its id or its name (tcpcal tools lists them)"),
]


def resolve_robot(ref: str) -> str:
    """The id of the robot `ref` names: an id or a robot name (unique: names are). Exit 5
    when none matches."""
    if _ID.match(ref):
        found = request("GET", f"/v1/robots/{ref}")
        if found.status_code == 200:
            return ref
        if found.status_code not in (404, 422):
            refused(found)
    for robot in fleet_robots():
        if robot["name"] == ref:
            return robot["id"]
    fail(EXIT_NOT_FOUND, f"no robot with id or name {ref!r}; tcpcal tools lists them")


def _fleet_rows(params: dict[str, str]) -> list[FleetTool]:
    """Every row of GET /v1/tools with these filters, page after page."""
    rows: list[FleetTool] = []
    cursor = None
    while True:
        query = {**params, "limit": "500", **({"cursor": cursor} if cursor else {})}
        body: Page[FleetTool] = send("GET", "/v1/tools", params=query).json()
        rows += body["items"]
        cursor = body["next_cursor"]
        if cursor is None:
            return rows


# ---- pose files ---------------------------------------------------------------------------
def read_poses(path: Path, fmt: str, units: dict[str, str]) -> JsonArray:
    """The poses of a pendant export, checked locally in `fmt` and `units` (exit 2 if not)."""
    from app.errors import InvalidInput
    from app.kinematics.poses import poses_from_format

    if not path.is_file():
        fail(EXIT_BAD_USE, f"no file {path}")
    text = path.read_text()
    if path.suffix.lower() == ".json":
        data = json.loads(text)
        poses: JsonArray = data["poses"] if isinstance(data, dict) else data
    else:
        poses = _csv_poses(path, text)
    if fmt != "joints":  # joint angles need the robot's model, which the server has
        try:
            poses_from_format(fmt, poses, units=units)
        except InvalidInput as exc:
            where = ".".join(str(p) for p in exc.loc)
            fail(EXIT_BAD_USE, f"{path}: {where}: {exc.detail}")
    return poses


def _csv_poses(path: Path, text: str) -> JsonArray:
    """Each row of numbers of a CSV export (a header line and # comments skipped)."""
    poses: JsonArray = []
    for row in csv.reader(text.splitlines()):
        cells = [c.strip() for c in row if c.strip()]
        if not cells or cells[0].startswith("#"):
            continue
        try:
            poses.append([float(c) for c in cells])
        except ValueError:
            if poses:  # a header is allowed on the first line only
                fail(EXIT_BAD_USE, f"{path}: not a row of numbers: {row}")
    return poses


def _units(length: str | None, angle: str | None) -> dict[str, str]:
    return {k: v for k, v in (("length", length), ("angle", angle)) if v is not None}


# ---- commands -----------------------------------------------------------------------------
def tools(
    cell: Annotated[str | None, typer.Option(help="only this cell")] = None,
    q: Annotated[str | None, typer.Option(help="tool or robot name prefix")] = None,
    status: Annotated[str | None, typer.Option(help="accepted | out_of_tolerance")] = None,
    csv_file: Annotated[Path | None, typer.Option("--csv", help="write the CSV here")] = None,
) -> None:
    """The fleet: every tool with its robot, active version, last calibration and check, why
    it needs attention, and its id (every other command takes the id or the tool's name)."""
    params = {k: v for k, v in (("cell", cell), ("q", q), ("status", status)) if v}
    if csv_file is not None:
        response = send("GET", "/v1/tools", params=params, headers={"Accept": "text/csv"})
        csv_file.write_text(response.text)
        out.print(f"wrote {csv_file} ({response.text.count(chr(10)) - 1} tools)")
        return
    table = Table(
        "tool", "slot", "robot", "cell", "active", "last calibration", "rms mm", "check",
        "controller", "attention",
    )  # fmt: skip
    table.add_column("id", no_wrap=True, overflow="ignore", min_width=36)
    for row in _fleet_rows(params):
        table.add_row(*_fleet_cells(row))
    out.print(table)


def _fleet_cells(row: FleetTool) -> list[str]:
    """One tool's cells in `tcpcal tools`' table."""
    cal, chk = row["last_calibration"], row["last_check"]
    rms = cal.get("rms_mm") if cal else None
    return [
        row["name"],
        "" if row["slot"] is None else str(row["slot"]),
        row["robot_name"],
        row["cell"] or "",
        "-" if row["active_version"] is None else f"v{row['active_version']}",
        cal["status"] if cal else "-",
        "" if rms is None else f"{rms:.3f}",
        _check_word(chk),
        _controller_word(row),
        ", ".join(row.get("attention", [])),
        row["id"],
    ]


def _check_word(chk: LastCheck | None) -> str:
    """ "ok", "FAILED", or a re-check that corrected the TCP as that: "corrected to v7" (it
    read "FAILED", the check's within_tolerance)."""
    if chk is None:
        return "-"
    verdict = chk.get("verdict")
    if verdict in ("corrected", "deployment_failed"):
        to = chk.get("correction_version")
        words = "corrected" if to is None else f"corrected to v{to}"
        return f"{words}, not deployed" if verdict == "deployment_failed" else words
    return "ok" if chk["within_tolerance"] else "FAILED"


def _controller_word(row: FleetTool) -> str:
    """The controller state the last look found, and, when it compared another version than
    the active one, which and when: "v5 in sync at 22:29 UTC; v6 not compared yet"."""
    ctl = row.get("controller")
    if ctl is None:
        return "-"
    state = ctl["state"].replace("_", " ")
    version, active = ctl.get("version"), row["active_version"]
    if version is not None and active is not None and version != active:
        at = ctl["checked_at"][11:16]
        return f"v{version} {state} at {at} UTC; v{active} not compared yet"
    return state


def calibrate(
    tool_id: ToolArg,
    poses_file: Annotated[
        Path | None, typer.Argument(help="CSV or JSON file of flange poses (not with --guided)")
    ] = None,
    fmt: Annotated[
        str,
        typer.Option(
            "--format",
            help="pose format, e.g. kuka_abc (--guided --session: the session's; --capture: "
            "default the controller's pendant's)",
        ),
    ] = "",
    length: Annotated[str | None, typer.Option(help="mm | m (default: the format's)")] = None,
    angle: Annotated[str | None, typer.Option(help="deg | rad (default: the format's)")] = None,
    method: Annotated[
        str | None, typer.Option(help="calibration method (default: GET /v1/methods' guided one)")
    ] = None,
    activate: Annotated[str, typer.Option(help="auto | always | never")] = "auto",
    note: Annotated[str | None, typer.Option(help="why, for the tool's history")] = None,
    guided: Annotated[
        bool, typer.Option(help="touch by touch: read each pose from stdin, show the next")
    ] = False,
    target: Annotated[float | None, typer.Option(help="--guided: done at this sigma, mm")] = None,
    session: Annotated[str | None, typer.Option(help="--guided: continue this session")] = None,
    capture: Annotated[
        bool,
        typer.Option(
            help="--guided: Enter reads each touch from the robot's controller (a typed line "
            "is still a typed pose)"
        ),
    ] = False,
) -> None:
    """Calibrate a tool from a pendant's pose export, or --guided touch by touch (the server
    says which orientation to touch next and when the TCP is known well enough), typed or
    with --capture read from the robot's controller; prints the verdict sentence."""
    units = _units(length, angle)
    if not fmt and not guided:  # --guided: the session's, or the controller's with --capture
        fail(EXIT_BAD_USE, "give --format, the pendant's pose format (e.g. kuka_abc)")
    if capture and not guided:
        fail(EXIT_BAD_USE, "--capture reads touches one at a time: give --guided too")
    ref, tool_id = tool_id, resolve_tool(tool_id)
    if guided:
        cal = guided_session(tool_id, fmt, units, target, session, activate, note, capture=capture)
        _print_calibration(cal, ref)
        return
    if poses_file is None:
        fail(EXIT_BAD_USE, "give a poses file, or --guided to touch one pose at a time")
    poses = read_poses(poses_file, fmt, units)
    body: JsonObject = {"method": method or guided_method(), "format": fmt, "poses": poses}
    body["activate"] = activate
    if units:
        body["units"] = units
    if note:
        body["note"] = note
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=err, transient=True) as progress:  # fmt: skip
        progress.add_task(f"sending {len(poses)} poses and solving", total=None)
        cal = send("POST", f"/v1/tools/{tool_id}/calibrations", json=body).json()
    _print_calibration(cal, ref)


def _force_advice(ref: str, version: int) -> str:
    """How to put a version stored out of tolerance live anyway, as this CLI's flags."""
    return (
        f'to put it live anyway: tcpcal activate {ref} {version} --force --reason "<why>"; '
        "or calibrate again"
    )


#: The advice a result held for its change gives an API client (app.services.calibrations
#: .verdict.change_warning), and the same said as this CLI's commands.
_HELD_FOR_CHANGE = re.compile(
    r"\(POST /v1/tools/\{tool_id\}/versions/\{version\}/activate\) or resend with "
    r'activate: "always"'
)


def _as_flags(warning: str, ref: str, cal: Calibration) -> str:
    """A server's warning with its advice for an HTTP client said as this CLI's commands."""
    return _HELD_FOR_CHANGE.sub(
        f"(tcpcal activate {ref} {cal['version']}) or calibrate again with --activate always",
        warning,
    )


def _print_calibration(cal: Calibration, ref: str) -> None:
    table = Table("version", "status", "active", "x mm", "y mm", "z mm", "rms mm", "touches")
    x, y, z = cal["tcp"]["position_mm"]
    rms = cal["quality"].get("rms_mm")
    table.add_row(
        str(cal["version"]), cal["status"], "yes" if cal["active"] else "no",
        f"{x:.3f}", f"{y:.3f}", f"{z:.3f}", "" if rms is None else f"{rms:.3f}",
        str(cal["quality"]["n_poses"]),
    )  # fmt: skip
    out.print(table)
    out.print(cal["summary"], highlight=False)
    for warning in cal["warnings"]:
        err.print(f"[yellow]warning[/]: {escape(_as_flags(warning, ref, cal))}", highlight=False)
    if cal["status"] != "accepted":
        if not cal["active"]:
            out.print(
                f"version {cal['version']} is stored, not active; "
                + _force_advice(ref, cal["version"]),
                highlight=False,
                soft_wrap=True,
            )
        raise typer.Exit(EXIT_OUT_OF_TOLERANCE)


def plan(
    start: Annotated[str, typer.Option(help="the start pose touching the point, as numbers")],
    fmt: Annotated[str, typer.Option("--format", help="pose format, e.g. kuka_abc")],
    tool: Annotated[
        str | None, typer.Option(help="use this tool's active TCP (id, name or robot/tool)")
    ] = None,
    tcp: Annotated[str | None, typer.Option(help="approximate TCP 'x y z' mm")] = None,
    noise: Annotated[float, typer.Option(help="touch noise, mm 1-sigma")] = 0.05,
    tilt: Annotated[float, typer.Option(help="max tilt from the start's tool axis, deg")] = 40,
    spin: Annotated[float, typer.Option(help="max spin about the tool axis, deg")] = 90,
    n: Annotated[int | None, typer.Option(help="how many touches")] = None,
    target: Annotated[float | None, typer.Option(help="fewest touches reaching this, mm")] = None,
    csv_file: Annotated[Path | None, typer.Option("--csv", help="write the poses here")] = None,
) -> None:
    """Which touches to make before the robot moves: poses within the reachable cone that
    determine the TCP best, with the predicted uncertainty."""
    body: JsonObject = {
        "format": fmt,
        "start": [float(v) for v in start.replace(",", " ").split()],
        "touch_noise_mm": noise,
        "max_tilt_deg": tilt,
        "max_spin_deg": spin,
    }
    if tool:
        body["tool_id"] = resolve_tool(tool)
    if tcp:
        body["tcp_mm"] = [float(v) for v in tcp.replace(",", " ").split()]
    if n is not None:
        body["n_poses"] = n
    if target is not None:
        body["target_sigma_mm"] = target
    from app.kinematics.poses import format_components

    result: Plan = send("POST", "/v1/plan", json=body).json()
    names = format_components(fmt)  # the server accepted the format: it is a known one
    table = Table("touch", *names)
    rows = [flat_pose(p) for p in result["poses"]]
    for i, row in enumerate(rows, start=1):
        table.add_row(str(i), *[f"{v:.3f}" for v in row])
    out.print(table)
    sx, sy, sz = result["predicted_tcp_sigma_mm"]
    out.print(
        f"{result['n_poses']} touches: predicted TCP 1-sigma {sx:.4f} {sy:.4f} {sz:.4f} mm, "
        f"RMS error {result['predicted_sigma_mm']:.4f} mm",
        highlight=False,
    )
    if csv_file is not None:
        # The header names each number; `tcpcal calibrate --poses` reads the file as it is.
        with csv_file.open("w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(names)
            writer.writerows(rows)
        out.print(f"wrote {csv_file}")


def history(tool_id: ToolArg) -> None:
    """A tool's versions (status, who, when, why, which is active) and every activation with
    its reason."""
    tool_id = resolve_tool(tool_id)
    body: VersionList = send("GET", f"/v1/tools/{tool_id}/versions").json()
    table = Table(
        "version", "status", "active", "x mm", "y mm", "z mm", "source", "by", "at", "note",
        title="versions",
    )  # fmt: skip
    for v in body["items"]:
        x, y, z = v["tcp"]["position_mm"]
        table.add_row(
            str(v["version"]), v["status"], "*" if v["active"] else "", f"{x:.3f}", f"{y:.3f}",
            f"{z:.3f}", v["source"], v["created_by"], v["created_at"][:19], v.get("note") or "",
        )  # fmt: skip
    out.print(table)
    activations = Table("at", "version", "previous", "kind", "reason", "by", title="activations")
    for a in body.get("activations", []):
        activations.add_row(
            a["activated_at"][:19], str(a["version"]),
            "-" if a["previous_version"] is None else str(a["previous_version"]),
            a["reason"], a.get("reason_text") or "", a["activated_by"],
        )  # fmt: skip
    out.print(activations)


def _problem_kind(response: httpx.Response) -> str:
    """The last word of a problem's type: "out-of-tolerance", "controller-unreachable"."""
    return str(problem(response).get("type", "")).rsplit("/", 1)[-1]


def _etag(tool_id: str) -> str:
    """The tool's ETag now, sent as If-Match: a change made meanwhile is a 412, not undone."""
    return str(send("GET", f"/v1/tools/{tool_id}").headers.get("ETag", "*"))


def activate(
    tool_id: ToolArg,
    version: Annotated[int, typer.Argument(help="the version to make active")],
    reason: Annotated[
        str | None, typer.Option(help="why, kept in the history and the audit trail")
    ] = None,
    force: Annotated[
        bool, typer.Option(help="activate a version stored out of tolerance (needs --reason)")
    ] = False,
) -> None:
    """Make a version the tool's active TCP. A version stored out of tolerance needs --force
    and --reason."""
    if force and not reason:
        fail(EXIT_BAD_USE, "--force needs --reason: say why this version must go live")
    ref, tool_id = tool_id, resolve_tool(tool_id)
    body: JsonObject = {}
    if reason:
        body["reason"] = reason
    if force:
        body["force"] = True
    response = request(
        "POST",
        f"/v1/tools/{tool_id}/versions/{version}/activate",
        json=body,
        headers={"If-Match": _etag(tool_id)},
    )
    if response.status_code == 409 and _problem_kind(response) == "out-of-tolerance":
        # The server's advice is for an HTTP client ({"force": true, ...}); say it as flags.
        refusal = problem(response)
        worst = f" ({refusal['summary']})" if refusal.get("summary") else ""
        fail(
            EXIT_REFUSED,
            f"version {version} is stored as out_of_tolerance{worst}; nothing was changed; "
            + _force_advice(ref, version),
        )
    if response.status_code >= 400:
        refused(response)
    tool: Tool = response.json()
    out.print(f"tool {tool['name']}: version {tool['active_version']} is active")


def rollback(
    tool_id: ToolArg,
    reason: Annotated[
        str | None, typer.Option(help="why, kept in the history and the audit trail")
    ] = None,
) -> None:
    """Go back to the version that was active before the current one (from the activation
    history; again walks further back)."""
    tool_id = resolve_tool(tool_id)
    body: JsonObject = {"reason": reason} if reason else {}
    tool: Tool = send(
        "POST", f"/v1/tools/{tool_id}/rollback", json=body, headers={"If-Match": _etag(tool_id)}
    ).json()
    out.print(f"tool {tool['name']}: rolled back, version {tool['active_version']} is active")


def check(
    tool_id: ToolArg,
    reference_point_id: Annotated[
        str | None,
        typer.Argument(help="the reference point touched (typed poses; or --reference)"),
    ] = None,
    poses_file: Annotated[
        Path | None, typer.Argument(help="CSV or JSON file of flange poses (not with --capture)")
    ] = None,
    fmt: Annotated[
        str | None, typer.Option("--format", help="pose format of the file, e.g. kuka_abc")
    ] = None,
    length: Annotated[str | None, typer.Option(help="mm | m")] = None,
    angle: Annotated[str | None, typer.Option(help="deg | rad")] = None,
    capture: Annotated[
        bool,
        typer.Option(
            "--capture",
            help="read the one touch from the robot's controller: the robot stands with the "
            "TCP at the reference point",
        ),
    ] = False,
    reference: Annotated[
        str | None,
        typer.Option(help="the reference point by name or id (of the tool's robot)"),
    ] = None,
    correct: Annotated[
        bool,
        typer.Option(
            "--correct",
            help="with --capture: out of tolerance and within the tool's max_correction_mm, "
            "store the TCP this touch gives as a new version, activate and deploy it",
        ),
    ] = False,
    deploy: Annotated[
        bool, typer.Option(help="deploy the correction to the controller and read it back")
    ] = True,
    reason: Annotated[
        str | None, typer.Option(help="why (e.g. the collision), kept with the correction")
    ] = None,
    idempotency_key: Annotated[
        str | None, typer.Option(help="retry-safe: the same key replays the first answer")
    ] = None,
) -> None:
    """Touch a reference point with the active TCP: how far and which way the tool moved.
    After a collision: --capture --reference NAME --correct reads the touch from the robot,
    and corrects, activates and deploys the TCP when it moved within max_correction_mm."""
    if reference and reference_point_id:
        fail(EXIT_BAD_USE, "name the reference point once: as an argument or with --reference")
    point = reference or reference_point_id
    if point is None:
        fail(EXIT_BAD_USE, "name the reference point: --reference NAME (or its id as argument)")
    if capture:
        if poses_file is not None or fmt is not None or length or angle:
            fail(EXIT_BAD_USE, "--capture reads the touch from the robot: leave out the poses")
        recheck(
            resolve_tool(tool_id),
            point,
            correct=correct,
            deploy=deploy,
            reason=reason,
            idempotency_key=idempotency_key,
        )
    if poses_file is None or fmt is None or correct or reason or idempotency_key:
        fail(
            EXIT_BAD_USE,
            "typed: REFERENCE_POINT POSES_FILE --format FORMAT; --correct, --reason and "
            "--idempotency-key go with --capture",
        )
    _typed_check(resolve_tool(tool_id), point, poses_file, fmt, _units(length, angle))


def _typed_check(
    tool_id: str, point_id: str, poses_file: Path, fmt: str, units: dict[str, str]
) -> None:
    """The check of poses typed on the pendant and exported: exit 3 when out of tolerance."""
    body: JsonObject = {
        "reference_point_id": point_id,
        "format": fmt,
        "poses": read_poses(poses_file, fmt, units),
    }
    if units:
        body["units"] = units
    result: CheckResult = send("POST", f"/v1/tools/{tool_id}/checks", json=body).json()
    out.print(result["summary"], highlight=False)
    if not result["within_tolerance"]:
        raise typer.Exit(EXIT_OUT_OF_TOLERANCE)


def export(
    tool_id: Annotated[
        str | None,
        typer.Argument(
            metavar="TOOL",
            help="the tool: its id, its name when only one tool has it, or robot/tool "
            "(not with --all)",
        ),
    ] = None,
    fmt: Annotated[
        str | None,
        typer.Option(
            "--format",
            help=f"{' | '.join(CONTROLLER_FORMATS)} (with --all: default the formats of "
            "each robot's vendor, every format when it is not known)",
        ),
    ] = None,
    output: Annotated[Path | None, typer.Option("-o", "--output", help="file or directory")] = None,
    all_dir: Annotated[
        Path | None,
        typer.Option(
            "--all",
            help="write every robot's files into this directory: DIR/<robot>/<file>, a fleet "
            "backup a technician can restore from",
        ),
    ] = None,
    merge_into: Annotated[
        Path | None,
        typer.Option(
            "--merge-into",
            help="the controller's own TOOL.CND (--format 'yaskawa'), saved from it; the file "
            "written is "
            "that file with this tool's block replaced and every other tool kept (loading "
            "TOOL.CND loads the whole tool file)",
        ),
    ] = None,
) -> None:
    """Write the active TCP as the file the controller loads, or (--all DIR) every robot's."""
    if all_dir is not None:
        if tool_id is not None or output is not None or merge_into is not None:
            fail(
                EXIT_BAD_USE,
                "--all DIR writes every robot's files: give no tool id, -o or --merge-into",
            )
        _export_all(all_dir, fmt)
        return
    if merge_into is not None and fmt != "yaskawa":
        fail(EXIT_BAD_USE, "--merge-into merges into a saved TOOL.CND: give --format 'yaskawa'")
    if tool_id is None or fmt is None:
        fail(EXIT_BAD_USE, "give a tool id and --format, or --all DIR")
    tool_id = resolve_tool(tool_id)
    response = send(
        "GET", f"/v1/tools/{tool_id}/tcp", params={"format": fmt}, headers={"Accept": "text/plain"}
    )
    name = _file_name(response) or f"{tool_id}.{fmt}.txt"
    target = output or Path(name)
    if target.is_dir():
        target = target / name
    text = response.text if merge_into is None else _merged_cnd(merge_into, response.text)
    target.write_text(text)
    out.print(f"wrote {target}")
    if fmt == "yaskawa" and merge_into is None:
        from app.vendors.yaskawa.file import WHOLE_FILE_NOTE

        out.print(WHOLE_FILE_NOTE, highlight=False)


def _merged_cnd(saved: Path, ours: str) -> str:
    """The controller's saved TOOL.CND with our blocks in place (exit 2 naming the problem)."""
    from app.errors import InvalidInput
    from app.vendors.yaskawa.file import merge

    try:
        return merge(saved.read_text(encoding="ascii", errors="replace"), ours)
    except (OSError, InvalidInput) as exc:
        fail(EXIT_BAD_USE, f"--merge-into {saved}: {getattr(exc, 'detail', exc)}")


def _file_name(response: httpx.Response) -> str | None:
    """The file name Content-Disposition gives, without any directory part."""
    disposition = response.headers.get("Content-Disposition", "")
    if "filename=" not in disposition:
        return None
    return Path(disposition.split('filename="')[-1].rstrip('"')).name or None


def fleet_robots() -> list[Robot]:
    """Every robot of the fleet (GET /v1/robots), page after page."""
    robots: list[Robot] = []
    cursor: str | None = None
    while True:
        params: dict[str, str | int] = {"limit": 200}
        if cursor:
            params["cursor"] = cursor
        page: Page[Robot] = send("GET", "/v1/robots", params=params).json()
        robots.extend(page["items"])
        cursor = page.get("next_cursor")
        if not cursor:
            return robots


def _export_all(directory: Path, fmt: str | None) -> None:
    """DIR/<robot>/: each format's file of the robot's tools, and the tool table as JSON."""
    from app.vendors.names import file_stem
    from app.vendors.registry import vendor_formats

    robots = fleet_robots()
    used: set[str] = set()
    for robot in robots:
        folder_name = file_stem(robot["name"], 80)
        while folder_name.lower() in used:
            folder_name += "_"
        used.add(folder_name.lower())
        folder = directory / folder_name
        folder.mkdir(parents=True, exist_ok=True)
        path = f"/v1/robots/{robot['id']}/tool-table"
        table = send("GET", path).json()
        (folder / "tool-table.json").write_text(json.dumps(table, indent=2) + "\n")
        for each in (fmt,) if fmt else vendor_formats(robot.get("vendor")):
            response = send("GET", path, params={"format": each}, headers={"Accept": "text/plain"})
            target = folder / (_file_name(response) or f"tools.{each}.txt")
            target.write_text(response.text)
            out.print(f"wrote {target}", highlight=False)
            if each == "yaskawa":  # TOOL.CND cannot say it itself: no comment syntax
                from app.vendors.yaskawa.file import WHOLE_FILE_NOTE

                note = target.with_name(target.name + ".README.txt")
                note.write_text(WHOLE_FILE_NOTE + "\n")
                out.print(f"wrote {note}", highlight=False)
    out.print(f"{len(robots)} robot(s) written to {directory}", highlight=False)


# ---- the audit trail ----------------------------------------------------------------------
def audit(
    tool_id: Annotated[
        str | None, typer.Option("--tool", help="only this tool: its id, name or robot/tool")
    ] = None,
    robot_id: Annotated[
        str | None, typer.Option("--robot", help="only this robot: its id or name")
    ] = None,
    action: Annotated[str | None, typer.Option(help="e.g. version.activate, tool.update")] = None,
    actor: Annotated[str | None, typer.Option(help="only this key's changes (its name)")] = None,
    since: Annotated[
        str | None, typer.Option(help="from this time, e.g. 2026-11-24T06:00Z")
    ] = None,
    until: Annotated[str | None, typer.Option(help="before this time")] = None,
    limit: Annotated[int, typer.Option(min=1, max=10_000, help="at most this many")] = 50,
) -> None:
    """The audit trail, newest first: when, who, what, which tool and version, and why
    (needs an admin key)."""
    filters = {
        "tool_id": None if tool_id is None else resolve_tool(tool_id),
        "robot_id": None if robot_id is None else resolve_robot(robot_id),
        "action": action,
        "actor": actor,
        "since": since,
        "until": until,
    }
    events = _audit_events({k: v for k, v in filters.items() if v}, limit)
    names = tool_names({e["tool_id"] for e in events if e["tool_id"]})
    _print_audit([_audit_row(e, names) for e in events])
    if not events:
        out.print("no audit events match")


def _audit_row(event: AuditEvent, names: dict[str, str]) -> tuple[str, str, str, str, str]:
    """When, who, what, which tool and version (a deployment's from its detail), and why."""
    detail = event["detail"] or {}
    tool = names.get(event["tool_id"], "") if event["tool_id"] else ""
    number = event["version"] if event["version"] is not None else detail.get("version")
    version = "" if number is None else f"v{number}"
    return (
        event["at"][:19].replace("T", " "),
        event["actor"],
        event["action"],
        " ".join(p for p in (tool, version) if p),
        audit_why(event["action"], detail),
    )


#: Below this many columns a five-column table wraps "why" to a word a line: each event is
#: printed as a line of when, who, what, tool and version, and its why indented below.
AUDIT_TABLE_MIN_WIDTH = 120


def _print_audit(rows: list[tuple[str, str, str, str, str]]) -> None:
    """The events as a table on a wide terminal, as two lines each on a narrow one."""
    if out.width >= AUDIT_TABLE_MIN_WIDTH:
        table = Table("when (UTC)", "who", "what", "tool / version", "why", box=box.SIMPLE)
        for row in rows:
            table.add_row(*row)
        out.print(table)
        return
    out.print("when (UTC)  who  what  tool / version\n    why", highlight=False)
    for when, who, what, tool, why in rows:
        out.print(f"{when}  {who}  {what}  {tool}".rstrip(), highlight=False, soft_wrap=True)
        if why:
            out.print(Padding(why, (0, 0, 0, 4)), highlight=False)


def _audit_events(params: dict[str, str], limit: int) -> list[AuditEvent]:
    """Up to `limit` audit events matching `params`, newest first, page after page."""
    events: list[AuditEvent] = []
    cursor = None
    while len(events) < limit:
        page_params: Params = {
            **params,
            "limit": min(500, limit - len(events)),
            **({"cursor": cursor} if cursor else {}),
        }
        body: Page[AuditEvent] = send("GET", "/v1/audit", params=page_params).json()
        events += body["items"]
        cursor = body["next_cursor"]
        if cursor is None:
            break
    return events


def tool_names(tool_ids: set[str]) -> dict[str, str]:
    """Each tool's name (its id's first 8 characters when it cannot be read: archived)."""
    import httpx

    names = {}
    with client_http.connect() as http:
        for tid in sorted(tool_ids):
            try:
                response = http.get(f"/v1/tools/{tid}")
            except httpx.HTTPError:
                names[tid] = tid[:8]
                continue
            tool: Tool | None = response.json() if response.status_code == 200 else None
            names[tid] = tool["name"] if tool else tid[:8]
    return names


def audit_why(action: str, detail: JsonObject) -> str:
    """The reason or the change an audit event records, in a few words: no `None`, figures
    rounded to what a person reads (mm and deg to 3 decimals), errors in their own words."""
    if "kind" in detail:  # an activation or a rollback
        return _activation_why(detail)
    if action == "tool.deploy":
        return _deploy_why(detail)
    if action.startswith("controller.") and "previous_state" in detail:
        return _state_why(action.removeprefix("controller."), detail)
    if "changed" in detail:
        return _changes_text(detail)
    if action == "calibration.create":
        note = f": {detail['note']}" if detail.get("note") else ""
        return f"{detail.get('method')} {detail.get('status')}{note}"
    if detail.get("summary"):
        return str(detail["summary"])
    shown = {
        k: v
        for k, v in detail.items()
        if v is not None and (not isinstance(v, dict | list) or k == "cells")
    }
    return ", ".join(f"{k} {_shown(v)}" for k, v in shown.items())


def _shown(value: object) -> str:
    """A stored value as a person reads it: floats to 3 decimals (0.5, 0.3, 0), lists
    joined, no None."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):  # 3 decimals, and no zeros after the last digit that counts
        return f"{value:.3f}".rstrip("0").rstrip(".").replace("-0", "0") or "0"
    if isinstance(value, list):
        return ", ".join(_shown(v) for v in value)
    return str(value)


def _activation_why(detail: JsonObject) -> str:
    """ "forced: probe bent (was v3)", "explicit (was v1)", "rollback: crash (was v4)"."""
    kind, reason = detail["kind"], detail.get("reason")
    words = str(kind) if reason in (None, kind) else f"{kind}: {reason}"
    if detail.get("force") and kind != "forced":
        words = f"forced, {words}"
    previous = detail.get("previous_version")
    return words + ("" if previous is None else f" (was v{previous})")


def _deploy_why(detail: JsonObject) -> str:
    """ "verified at $TOOL_DATA[3] (kuka_kvp)" or the status and the error's own words."""
    words = f"{detail.get('status')} at {detail.get('target')} ({detail.get('protocol')})"
    error = detail.get("error")
    if isinstance(error, dict) and error.get("detail"):
        words += f": {error['detail']}"
    if detail.get("reason"):
        words += f"; why: {detail['reason']}"
    return words


def _state_why(state: str, detail: JsonObject) -> str:
    """ "drifted at UTOOL[3] (was in_sync): off by 0.000 mm, 0.500 deg"."""
    was = detail.get("previous_state")
    words = f"{state} at {detail.get('target')}" + ("" if was is None else f" (was {was})")
    mm, deg = detail.get("deviation_mm"), detail.get("deviation_deg")
    if state == "drifted" and isinstance(mm, float | int) and isinstance(deg, float | int):
        words += f": off by {mm:.3f} mm, {deg:.3f} deg"
    if detail.get("error"):
        words += f": {detail['error']}"
    return words


def _changes_text(detail: JsonObject) -> str:
    """`field old -> new` for each changed field with values (nested: each changed member)."""
    old, new = detail.get("from", {}), detail.get("to", {})
    parts = []
    for field in detail["changed"]:
        if field not in new:
            parts.append(field)
        elif isinstance(new[field], dict) and isinstance(old.get(field), dict):
            before = old[field]
            parts += [
                f"{field}.{k} {_shown(before.get(k))} -> {_shown(v)}"
                for k, v in new[field].items()
                if before.get(k) != v
            ]
        else:
            parts.append(f"{field} {_shown(old.get(field))} -> {_shown(new[field])}")
    return "; ".join(parts)
