"""`tcpcal deploy TOOL` and `tcpcal reconcile ROBOT`: the controller commands of the client.

Exit codes (for scripts and cell PCs): 0 verified / in sync; 2 mismatch / drifted; 3 the
controller is unreachable; 4 refused (by the controller, in its own words, or by the
server: no active version, no slot or symbol); 5 not found or not allowed; 6 the server could
not be reached or failed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from app.client_bodies import Deployment, Frame, Reconciliation
from app.client_http import (
    EXIT_NOT_FOUND,
    EXIT_REFUSED,
    EXIT_UNREACHABLE,
    err,
    out,
    problem,
    request,
)

if TYPE_CHECKING:
    import httpx

EXIT_DRIFTED = 2
EXIT_CONTROLLER_UNREACHABLE = 3
_EXITS = """Exit codes: 0 verified / in sync; 2 mismatch / drifted; 3 controller unreachable;
4 refused (by the controller or the server); 5 not found or not allowed; 6 server failed."""


def register(cli: typer.Typer) -> None:
    """Add the controller commands to the `tcpcal` command."""
    for command in (deploy, reconcile):
        cli.command(rich_help_panel="Client (talks to a server)", epilog=_EXITS)(command)


def _exit_for_problem(response: httpx.Response) -> int:
    """The exit code of a failed answer (the 502s by what the controller did)."""
    kind = str(problem(response).get("type", "")).rsplit("/", 1)[-1]
    by_kind = {
        "controller-unreachable": EXIT_CONTROLLER_UNREACHABLE,
        "controller-mismatch": EXIT_DRIFTED,
        "controller-refused": EXIT_REFUSED,
    }
    if kind in by_kind:
        return by_kind[kind]
    if response.status_code in (401, 403, 404):
        return EXIT_NOT_FOUND
    return EXIT_UNREACHABLE if response.status_code >= 500 else EXIT_REFUSED


def _frame(frame: Frame | None) -> str:
    if not frame:
        return "-"
    x, y, z = frame["position_mm"]
    w, qx, qy, qz = frame["quaternion"]
    return f"{x:.3f} {y:.3f} {z:.3f} | q {w:.5f} {qx:.5f} {qy:.5f} {qz:.5f}"


def _deviation(mm: float | None, deg: float | None) -> str:
    return "-" if mm is None or deg is None else f"{mm:.4f} mm {deg:.4f} deg"


def deploy(
    tool_id: Annotated[str, typer.Argument(help="the tool's id")],
    idempotency_key: Annotated[
        str | None, typer.Option(help="retry-safe: the same key replays the first answer")
    ] = None,
) -> None:
    """Write the tool's active TCP into its robot's controller and read it back."""
    headers = {"Idempotency-Key": idempotency_key} if idempotency_key else {}
    response = request("POST", f"/v1/tools/{tool_id}/deployments", json={}, headers=headers)
    if response.status_code >= 400:
        failed = problem(response)
        words = f" (deployment {failed['deployment_id']})" if "deployment_id" in failed else ""
        err.print(
            f"[bold red]{response.status_code}[/]: {failed.get('detail')}{words}",
            highlight=False,
        )
        raise typer.Exit(_exit_for_problem(response))
    dep: Deployment = response.json()
    table = Table("deployment", "version", "target", "status", "previous", "read back", "deviation")
    table.add_row(
        dep["id"],
        str(dep["version"]),
        dep["target"],
        dep["status"],
        _frame(dep["previous"]),
        _frame(dep["read_back"]),
        _deviation(dep["deviation_mm"], dep["deviation_deg"]),
    )
    out.print(table)
    out.print(
        f"{dep['status']}: {dep['target']} holds version {dep['version']}",
        highlight=False,
        soft_wrap=True,
    )


def reconcile(robot_id: Annotated[str, typer.Argument(help="the robot's id")]) -> None:
    """Read every tool's frame from the robot's controller and compare it with the active
    TCP (in sync within 0.01 mm and 0.01 deg)."""
    response = request("POST", f"/v1/robots/{robot_id}/reconcile")
    if response.status_code >= 400:
        err.print(f"[bold red]{response.status_code}[/]: {problem(response).get('detail')}")
        raise typer.Exit(_exit_for_problem(response))
    result: Reconciliation = response.json()
    table = Table("tool", "target", "state", "since", "controller", "active", "deviation")
    for t in result["tools"]:
        active = t["active"]
        table.add_row(
            t["tool_id"],
            t["target"] or "-",
            t["state"] + (f" ({t['error']})" if t.get("error") else ""),
            t["since"],
            _frame(t["controller"]),
            "-" if active is None else f"v{active['version']}: {_frame(active)}",
            _deviation(t["deviation_mm"], t["deviation_deg"]),
        )
    out.print(table)
    for t in result["tools"]:
        if t["state"] == "drifted":
            out.print(
                f"drifted: {t['tool_id']} at {t['target']} is off by "
                f"{_deviation(t['deviation_mm'], t['deviation_deg'])}",
                highlight=False,
                soft_wrap=True,
            )
    for skipped in result.get("not_addressable", []):
        out.print(
            f"left out {skipped['tool_id']}: {skipped['reason']}", highlight=False, soft_wrap=True
        )
    out.print(f"robot {result['robot_id']}: {result['state']}", highlight=False, soft_wrap=True)
    exits = {"in_sync": 0, "drifted": EXIT_DRIFTED, "unreachable": EXIT_CONTROLLER_UNREACHABLE}
    raise typer.Exit(exits[result["state"]])
