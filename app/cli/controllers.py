"""`tcpcal deploy TOOL` and `tcpcal reconcile ROBOT`: the controller commands of the client.

Exit codes (for scripts and cell PCs): 0 verified / in sync; 3 the controller is
unreachable; 4 refused (by the controller, in its own words, or by the server: no active
version, no slot or symbol); 5 not found or not allowed; 6 the server could not be reached
or failed; 8 mismatch / drifted; 2 bad use (typer's: an unknown option, a missing argument).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer
from rich import box
from rich.table import Table

from app.cli.bodies import Deployment, Frame, ReconciledTool, Reconciliation
from app.cli.client import RobotArg, ToolArg, resolve_robot, resolve_tool, tool_names
from app.cli.http import EXIT_NOT_FOUND, EXIT_REFUSED, EXIT_UNREACHABLE, err, out, problem, request

if TYPE_CHECKING:
    import httpx

#: What a `live` scope deployment means, for the person at the cell (contract v1.3).
LIVE_SCOPE = (
    "live: the robot holds this TCP only for the running program; the next program start "
    "sets its own TCP, and the reconcile rounds then show what the robot moves by"
)

#: Not 2: typer exits 2 for bad use (an unknown option, a missing argument), and a cell PC's
#: script must not read a typo as "drifted"; 4 to 6 are every command's (app.cli.http), 7 is
#: check --capture's "needs recalibration" (app.cli.recheck).
EXIT_DRIFTED = 8
EXIT_CONTROLLER_UNREACHABLE = 3
_EXITS = """Exit codes: 0 verified / in sync; 3 controller unreachable; 4 refused (by the
controller or the server); 5 not found or not allowed; 6 server failed; 8 mismatch / drifted;
2 bad use."""


def register(cli: typer.Typer) -> None:
    """Add the controller commands to the `tcpcal` command."""
    for command in (deploy, reconcile):
        cli.command(rich_help_panel="Client (talks to a server)", epilog=_EXITS)(command)


def exit_for_problem(response: httpx.Response) -> int:
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
    return f"{x:.3f} {y:.3f} {z:.3f} mm | q {w:.5f} {qx:.5f} {qy:.5f} {qz:.5f}"


def _deviation(mm: float | None, deg: float | None) -> str:
    return "-" if mm is None or deg is None else f"{mm:.4f} mm, {deg:.4f} deg"


def _lines(rows: list[tuple[str, str]]) -> None:
    """Label and value lines, never cut: a target such as $TOOL_DATA[16] or
    T_ROB1/user/tTorch must reach a technician whole, at any terminal width."""
    width = max(len(label) for label, _ in rows)
    for label, value in rows:
        out.print(f"  {label:<{width}}  {value}", highlight=False, soft_wrap=True)


def deploy(
    tool_ref: ToolArg,
    idempotency_key: Annotated[
        str | None, typer.Option(help="retry-safe: the same key replays the first answer")
    ] = None,
    reason: Annotated[
        str | None,
        typer.Option(help="why it is deployed (1-500 characters), kept with the deployment"),
    ] = None,
) -> None:
    """Write the tool's active TCP into its robot's controller and read it back."""
    tool_id = resolve_tool(tool_ref)
    headers = {"Idempotency-Key": idempotency_key} if idempotency_key else {}
    body = {} if reason is None else {"reason": reason}
    response = request("POST", f"/v1/tools/{tool_id}/deployments", json=body, headers=headers)
    if response.status_code >= 400:
        failed = problem(response)
        # The detail ends with what the controller may hold, in words ("nothing was
        # written: ...", "written, not confirmed: ..."); the status follows it.
        err.print(
            f"[bold red]{response.status_code}[/]: {failed.get('detail')}",
            highlight=False,
            soft_wrap=True,
        )
        if "deployment_id" in failed and "deployment_status" in failed:
            err.print(
                f"deployment {failed['deployment_id']}: {failed['deployment_status']}",
                highlight=False,
            )
        raise typer.Exit(exit_for_problem(response))
    dep: Deployment = response.json()
    name = tool_names({tool_id}).get(tool_id, tool_ref)
    out.print(f"deployment {dep['id']} of {name}: {dep['status']}", highlight=False)
    rows = [
        ("version", f"v{dep['version']}"),
        ("target", dep["target"]),
        ("previous", _frame(dep["previous"])),
        ("read back", _frame(dep["read_back"])),
        ("deviation", _deviation(dep["deviation_mm"], dep["deviation_deg"])),
    ]
    given = dep.get("reason")
    if given:
        rows.append(("reason", given))
    _lines(rows)
    out.print(
        f"{dep['status']}: {dep['target']} holds version {dep['version']}",
        highlight=False,
        soft_wrap=True,
    )
    if dep.get("scope") == "live":
        out.print(LIVE_SCOPE, highlight=False, soft_wrap=True)


def reconcile(robot_ref: RobotArg) -> None:
    """Read every tool's frame from the robot's controller and compare it with the active
    TCP (in sync within 0.01 mm and 0.01 deg)."""
    robot_id = resolve_robot(robot_ref)
    response = request("POST", f"/v1/robots/{robot_id}/reconcile")
    if response.status_code >= 400:
        err.print(
            f"[bold red]{response.status_code}[/]: {problem(response).get('detail')}",
            highlight=False,
            soft_wrap=True,
        )
        raise typer.Exit(exit_for_problem(response))
    result: Reconciliation = response.json()
    skipped = result.get("not_addressable", [])
    names = tool_names({t["tool_id"] for t in [*result["tools"], *skipped]})
    # Only the tool's name and the time may wrap: a state, a deviation or a target cut
    # to "$TOOL_D..." tells a technician nothing.
    table = Table(box=box.SIMPLE)
    for column, wraps in (
        ("tool", True), ("state", False), ("deviation", False), ("since (UTC)", True),
        ("target", False),
    ):  # fmt: skip
        table.add_column(column, no_wrap=not wraps)
    for t in result["tools"]:
        table.add_row(
            names.get(t["tool_id"], t["tool_id"]),
            t["state"],
            _deviation(t["deviation_mm"], t["deviation_deg"]),
            t["since"][:19].replace("T", " "),
            t["target"] or "-",
        )
    out.print(table)
    if result.get("scope") == "live":
        out.print(_live_words(result, names), highlight=False, soft_wrap=True)
    for t in result["tools"]:
        if t["state"] not in ("in_sync", "not_live"):
            _explain(names.get(t["tool_id"], t["tool_id"]), t)
    for left in skipped:
        name = names.get(left["tool_id"], left["tool_id"])
        out.print(f"left out {name}: {left['reason']}", highlight=False, soft_wrap=True)
    out.print(f"robot {robot_ref}: {result['state']}", highlight=False, soft_wrap=True)
    exits = {"in_sync": 0, "drifted": EXIT_DRIFTED, "unreachable": EXIT_CONTROLLER_UNREACHABLE}
    raise typer.Exit(exits[result["state"]])


def _live_words(result: Reconciliation, names: dict[str, str]) -> str:
    """Which tool a robot with one live TCP was judged by, and what live means."""
    live = f"{LIVE_SCOPE[0].upper()}{LIVE_SCOPE[1:]}"
    judged = [t for t in result["tools"] if t["state"] != "not_live"]
    if judged and all(t["state"] == "unreachable" for t in result["tools"]):
        return (
            "one live TCP: its controller could not be read, so no tool was judged and each "
            f"is unreachable. {live}"
        )
    if judged:
        which = f"{names.get(judged[0]['tool_id'], judged[0]['tool_id'])}, deployed to it last"
    else:
        which = "none: no tool was deployed to it from tcpcal yet"
    return (
        f"one live TCP: judged by {which}; its other tools are not_live (deploy one to make "
        f"it the live one). {live}"
    )


def _explain(name: str, tool: ReconciledTool) -> None:
    """What a tool that is not in sync holds, against its active version."""
    active = tool["active"]
    out.print(f"{tool['state']}: {name} at {tool['target']}", highlight=False, soft_wrap=True)
    rows = [("controller", _frame(tool["controller"]))]
    if active is not None:
        rows.append((f"active v{active['version']}", _frame(active)))
    if tool["state"] == "drifted":
        rows.append(("off by", _deviation(tool["deviation_mm"], tool["deviation_deg"])))
    if tool.get("error"):
        rows.append(("error", str(tool["error"])))
    _lines(rows)
