"""The cell PC's client: `tcpcal tools|calibrate|history|activate|rollback|check|export`.

Talks to a server over HTTP (TCPCAL_URL, default http://127.0.0.1:8000; TCPCAL_API_KEY).
Pose files exported from a pendant (CSV rows of numbers, or a JSON list of poses) are read
and checked locally in the given format and units before anything is sent.

Exit codes say what happened, for scripts on the cell PC:
0 done (a calibration accepted, a check within tolerance); 3 done but out of tolerance
(stored, not activated); 4 refused by the server (422/409/412: bad input, a unit or
convention mix-up, a conflict); 5 not found or not allowed (401/403/404); 6 the server could
not be reached or failed; 2 bad use or a pose file that does not read.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import Annotated, Any, NoReturn

import httpx
import typer
from rich.console import Console
from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

EXIT_OUT_OF_TOLERANCE = 3
EXIT_REFUSED = 4
EXIT_NOT_FOUND = 5
EXIT_UNREACHABLE = 6
EXIT_BAD_USE = 2

out = Console()
err = Console(stderr=True)


def register(cli: typer.Typer) -> None:
    """Add the client's commands to the `tcpcal` command."""
    for command in (tools, calibrate, history, activate, rollback, check, export):
        cli.command(rich_help_panel="Client (talks to a server)")(command)


# ---- HTTP ---------------------------------------------------------------------------------
def _http() -> httpx.Client:
    key = os.environ.get("TCPCAL_API_KEY")
    if not key:
        _fail(EXIT_BAD_USE, "set TCPCAL_API_KEY (and TCPCAL_URL if not http://127.0.0.1:8000)")
    url = os.environ.get("TCPCAL_URL", "http://127.0.0.1:8000")
    return httpx.Client(base_url=url, headers={"Authorization": f"Bearer {key}"}, timeout=120)


def _send(method: str, path: str, **kw: Any) -> httpx.Response:
    try:
        with _http() as http:
            response = http.request(method, path, **kw)
    except httpx.HTTPError as exc:
        _fail(EXIT_UNREACHABLE, f"could not reach {os.environ.get('TCPCAL_URL')}: {exc}")
    if response.status_code >= 400:
        _refused(response)
    return response


def _refused(response: httpx.Response) -> NoReturn:
    try:
        problem = response.json()
    except ValueError:
        problem = {"detail": response.text}
    detail = problem.get("detail") or response.reason_phrase
    if "suggestion" in problem:
        detail += f"\nsuggestion: {json.dumps(problem['suggestion'])}"
    code = response.status_code
    if code in (401, 403, 404):
        _fail(EXIT_NOT_FOUND, f"{code}: {detail}")
    if code >= 500:
        _fail(EXIT_UNREACHABLE, f"{code}: {detail}")
    _fail(EXIT_REFUSED, f"{code}: {detail}")


def _fail(code: int, message: str) -> NoReturn:
    err.print(f"[bold red]error[/]: {message}", highlight=False)
    raise typer.Exit(code)


# ---- pose files ---------------------------------------------------------------------------
def read_poses(path: Path, fmt: str, units: dict[str, str]) -> list[Any]:
    """The poses of a pendant export, checked locally in `fmt` and `units` (exit 2 if not)."""
    from app.errors import InvalidInput
    from app.kinematics.poses import poses_from_format

    if not path.is_file():
        _fail(EXIT_BAD_USE, f"no file {path}")
    text = path.read_text()
    poses: list[Any]
    if path.suffix.lower() == ".json":
        data = json.loads(text)
        poses = data["poses"] if isinstance(data, dict) else data
    else:
        poses = []
        for row in csv.reader(text.splitlines()):
            cells = [c.strip() for c in row if c.strip()]
            if not cells or cells[0].startswith("#"):
                continue
            try:
                poses.append([float(c) for c in cells])
            except ValueError:
                if poses:  # a header is allowed on the first line only
                    _fail(EXIT_BAD_USE, f"{path}: not a row of numbers: {row}")
    if fmt != "joints":  # joint angles need the robot's model, which the server has
        try:
            poses_from_format(fmt, poses, units=units)
        except InvalidInput as exc:
            where = ".".join(str(p) for p in exc.loc)
            _fail(EXIT_BAD_USE, f"{path}: {where}: {exc.detail}")
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
    """The fleet: every tool with its robot, active version, last calibration and check."""
    params = {k: v for k, v in (("cell", cell), ("q", q), ("status", status)) if v}
    if csv_file is not None:
        response = _send("GET", "/v1/tools", params=params, headers={"Accept": "text/csv"})
        csv_file.write_text(response.text)
        out.print(f"wrote {csv_file} ({response.text.count(chr(10)) - 1} tools)")
        return
    table = Table("tool", "slot", "robot", "cell", "active", "last calibration", "rms mm", "check")
    cursor = None
    while True:
        page = _send("GET", "/v1/tools", params={**params, "cursor": cursor} if cursor else params)
        body = page.json()
        for row in body["items"]:
            cal, chk = row["last_calibration"], row["last_check"]
            rms = cal.get("rms_mm") if cal else None
            table.add_row(
                row["name"],
                "" if row["slot"] is None else str(row["slot"]),
                row["robot_name"],
                row["cell"] or "",
                "-" if row["active_version"] is None else f"v{row['active_version']}",
                cal["status"] if cal else "-",
                "" if rms is None else f"{rms:.3f}",
                "-" if chk is None else ("ok" if chk["within_tolerance"] else "FAILED"),
            )
        cursor = body["next_cursor"]
        if cursor is None:
            break
    out.print(table)


def calibrate(
    tool_id: Annotated[str, typer.Argument(help="the tool's id (tcpcal tools)")],
    poses_file: Annotated[Path, typer.Argument(help="CSV or JSON file of flange poses")],
    fmt: Annotated[str, typer.Option("--format", help="pose format, e.g. kuka_abc")],
    length: Annotated[str | None, typer.Option(help="mm | m (default: the format's)")] = None,
    angle: Annotated[str | None, typer.Option(help="deg | rad (default: the format's)")] = None,
    method: Annotated[str, typer.Option(help="calibration method")] = "xyz_npoint",
    activate: Annotated[str, typer.Option(help="auto | always | never")] = "auto",
    note: Annotated[str | None, typer.Option(help="why, for the tool's history")] = None,
) -> None:
    """Calibrate a tool from a pendant's pose export; prints the verdict sentence."""
    units = _units(length, angle)
    poses = read_poses(poses_file, fmt, units)
    body: dict[str, Any] = {"method": method, "format": fmt, "poses": poses, "activate": activate}
    if units:
        body["units"] = units
    if note:
        body["note"] = note
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=err, transient=True) as progress:  # fmt: skip
        progress.add_task(f"sending {len(poses)} poses and solving", total=None)
        cal = _send("POST", f"/v1/tools/{tool_id}/calibrations", json=body).json()
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
        err.print(f"[yellow]warning[/]: {warning}", highlight=False)
    if cal["status"] != "accepted":
        raise typer.Exit(EXIT_OUT_OF_TOLERANCE)


def history(tool_id: Annotated[str, typer.Argument(help="the tool's id")]) -> None:
    """A tool's versions: who, when, why, which is active."""
    items = _send("GET", f"/v1/tools/{tool_id}/versions").json()["items"]
    table = Table("version", "active", "x mm", "y mm", "z mm", "source", "by", "at", "note")
    for v in items:
        x, y, z = v["tcp"]["position_mm"]
        table.add_row(
            str(v["version"]), "*" if v["active"] else "", f"{x:.3f}", f"{y:.3f}", f"{z:.3f}",
            v["source"], v["created_by"], v["created_at"][:19], v.get("note") or "",
        )  # fmt: skip
    out.print(table)


def _activate(tool_id: str, version: int) -> None:
    etag = _send("GET", f"/v1/tools/{tool_id}").headers.get("ETag", "*")
    tool = _send(
        "POST", f"/v1/tools/{tool_id}/versions/{version}/activate", headers={"If-Match": etag}
    ).json()
    out.print(f"tool {tool['name']}: version {tool['active_version']} is active")


def activate(
    tool_id: Annotated[str, typer.Argument(help="the tool's id")],
    version: Annotated[int, typer.Argument(help="the version to make active")],
) -> None:
    """Make a version the tool's active TCP."""
    _activate(tool_id, version)


def rollback(tool_id: Annotated[str, typer.Argument(help="the tool's id")]) -> None:
    """Activate the version before the active one."""
    items = _send("GET", f"/v1/tools/{tool_id}/versions").json()["items"]
    active = next((v["version"] for v in items if v["active"]), None)
    older = [v["version"] for v in items if active is not None and v["version"] < active]
    if not older:
        _fail(EXIT_REFUSED, "there is no version before the active one to roll back to")
    _activate(tool_id, max(older))


def check(
    tool_id: Annotated[str, typer.Argument(help="the tool's id")],
    reference_point_id: Annotated[str, typer.Argument(help="the reference point touched")],
    poses_file: Annotated[Path, typer.Argument(help="CSV or JSON file of flange poses")],
    fmt: Annotated[str, typer.Option("--format", help="pose format, e.g. kuka_abc")],
    length: Annotated[str | None, typer.Option(help="mm | m")] = None,
    angle: Annotated[str | None, typer.Option(help="deg | rad")] = None,
) -> None:
    """Touch a reference point with the active TCP: how far and which way the tool moved."""
    units = _units(length, angle)
    body: dict[str, Any] = {
        "reference_point_id": reference_point_id,
        "format": fmt,
        "poses": read_poses(poses_file, fmt, units),
    }
    if units:
        body["units"] = units
    result = _send("POST", f"/v1/tools/{tool_id}/checks", json=body).json()
    out.print(result["summary"], highlight=False)
    if not result["within_tolerance"]:
        raise typer.Exit(EXIT_OUT_OF_TOLERANCE)


def export(
    tool_id: Annotated[str, typer.Argument(help="the tool's id")],
    fmt: Annotated[
        str, typer.Option("--format", help="kuka | abb | fanuc | ur | yaskawa | techman")
    ],
    output: Annotated[Path | None, typer.Option("-o", "--output", help="file or directory")] = None,
) -> None:
    """Write the active TCP as the controller's own text to a file."""
    response = _send(
        "GET", f"/v1/tools/{tool_id}/tcp", params={"format": fmt}, headers={"Accept": "text/plain"}
    )
    disposition = response.headers.get("Content-Disposition", "")
    name = disposition.split('filename="')[-1].rstrip('"') if "filename=" in disposition else None
    target = output or Path(name or f"{tool_id}.{fmt}.txt")
    if target.is_dir():
        target = target / (name or f"{tool_id}.{fmt}.txt")
    target.write_text(response.text)
    out.print(f"wrote {target}")
