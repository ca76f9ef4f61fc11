"""The frames a robot's points are taught in and the tools standing in its cell:
`tcpcal frames [ROBOT]` lists a robot's frames, or the fleet's, each with its active origin.

Talks to the server as the rest of the client does (app.cli.http); the exit codes are the
client's (app.cli.client).
"""

from __future__ import annotations

from typing import Annotated

import typer
from rich.table import Table

from app.cli.bodies import ActiveRobotFrame, Page, Robot, RobotFrame
from app.cli.client import fleet_robots, resolve_robot
from app.cli.http import out, send


def register(cli: typer.Typer) -> None:
    """Add the frame commands to the `tcpcal` command."""
    cli.command(rich_help_panel="Client (talks to a server)")(frames)


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
