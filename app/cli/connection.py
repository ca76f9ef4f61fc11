"""`tcpcal connect ROBOT`, `tcpcal connection ROBOT` and `tcpcal disconnect ROBOT`: how the
server reaches a robot's controller (PUT, GET and DELETE /v1/robots/{id}/controller, admin
scope to change it).

The password never reaches the command line: `--password-stdin` reads it from the first line
of stdin (a secret store's pipe), `--password-prompt` asks for it without echo;
`--forget-password` removes the stored one (the API's `password: null`).
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Annotated

import typer

from app.cli.bodies import Controller
from app.cli.client import RobotArg, resolve_robot
from app.cli.controllers import LIVE_SCOPE, exit_for_problem
from app.cli.http import EXIT_BAD_USE, err, fail, out, problem, request
from app.jsontypes import JsonObject
from app.vendors.registry import SERVICE_PORTS
from app.words import PROTOCOLS

if TYPE_CHECKING:
    import httpx

_EXITS = """Exit codes: 0 done; 2 bad use; 4 refused by the server (a 422 names the option to
change); 5 robot not found, no connection or not allowed (admin scope to change it); 6 server
failed."""

#: The API's body fields, as this command's options (a 422 names the option to change).
_OPTIONS = {
    "protocol": "--protocol",
    "host": "--host",
    "port": "--port",
    "ports": "--ports",
    "username": "--user",
    "password": "--password-stdin",
    "timeout_s": "--timeout",
    "tls_verify": "--no-tls-verify",
}


def register(cli: typer.Typer) -> None:
    """Add the connection commands to the `tcpcal` command."""
    for command in (connect, connection, disconnect):
        cli.command(rich_help_panel="Client (talks to a server)", epilog=_EXITS)(command)


def address(controller: Controller) -> str:
    """Where the controller is reached, as the console writes it: host:port, or the host and
    each service's port for a protocol of several services."""
    ports = controller.get("ports")
    if not ports:
        return f"{controller['host']}:{controller['port']}"
    return f"{controller['host']} ({', '.join(f'{name} {port}' for name, port in ports.items())})"


def _show(robot_ref: str, controller: Controller) -> None:
    out.print(
        f"robot {robot_ref}: {controller['protocol']} at {address(controller)}",
        highlight=False,
        soft_wrap=True,
    )
    rows = [
        ("scope", controller["scope"]),
        ("user", controller.get("username") or "-"),
        ("password", "stored" if controller["has_password"] else "none"),
        ("timeout", f"{controller['timeout_s']:g} s"),
    ]
    if controller["protocol"] == "abb_rws2":
        rows.append(("tls verify", "yes" if controller["tls_verify"] else "no"))
    width = max(len(label) for label, _ in rows)
    for label, value in rows:
        out.print(f"  {label:<{width}}  {value}", highlight=False, soft_wrap=True)
    if controller["scope"] == "live":
        out.print(LIVE_SCOPE, highlight=False, soft_wrap=True)


def _refused(response: httpx.Response) -> None:
    """Say what the server refused, a 422 naming the option to change, and exit."""
    failed = problem(response)
    detail = str(failed.get("detail") or response.reason_phrase)
    errors = failed.get("errors")
    if response.status_code == 422 and isinstance(errors, list) and errors:
        loc = errors[0].get("loc") if isinstance(errors[0], dict) else None
        field = loc[1] if isinstance(loc, list) and len(loc) > 1 else None
        if isinstance(field, str) and field in _OPTIONS:
            detail = f"{_OPTIONS[field]}: {detail}"
    err.print(f"[bold red]{response.status_code}[/]: {detail}", highlight=False, soft_wrap=True)
    raise typer.Exit(exit_for_problem(response))


def _ports(given: list[str]) -> dict[str, int]:
    """`--ports SERVICE=PORT` options as the API's `ports` (exit 2 on a malformed one)."""
    ports: dict[str, int] = {}
    for item in given:
        service, sep, port = item.partition("=")
        if not sep or not service or not port.strip().isdigit():
            fail(
                EXIT_BAD_USE,
                f"--ports takes SERVICE=PORT, e.g. --ports listen_node=5890; got {item!r}",
            )
        ports[service.strip()] = int(port)
    return ports


def _password(from_stdin: bool, prompt: bool, forget: bool = False) -> str | None:
    """The password, read without it touching the command line or the screen; None: left
    out (the server keeps the stored one), or `forget` (it removes it)."""
    if from_stdin and prompt:
        fail(EXIT_BAD_USE, "give --password-stdin or --password-prompt, not both")
    if forget and (from_stdin or prompt):
        fail(
            EXIT_BAD_USE,
            "--forget-password removes the stored password: give it without --password-stdin "
            "or --password-prompt",
        )
    if from_stdin:
        line = sys.stdin.readline().rstrip("\r\n")
        if not line:
            fail(EXIT_BAD_USE, "--password-stdin: stdin's first line is empty")
        return line
    if prompt:
        return str(typer.prompt("password", hide_input=True, err=True))
    return None


def connect(
    robot_ref: RobotArg,
    protocol: Annotated[
        str,
        typer.Option(help=" | ".join(PROTOCOLS)),
    ],
    host: Annotated[str, typer.Option(help="the controller's host name or IP address")],
    port: Annotated[
        int | None,
        typer.Option(help="a single-service protocol's port (default: the protocol's)"),
    ] = None,
    ports: Annotated[
        list[str] | None,
        typer.Option(
            metavar="SERVICE=PORT",
            help="a protocol of several services, once per service, in place of --port: "
            + "; ".join(f"{name} {', '.join(ports)}" for name, ports in SERVICE_PORTS.items())
            + " (any left out keeps its default)",
        ),
    ] = None,
    user: Annotated[
        str | None, typer.Option(help="the controller's user (abb_rws1, abb_rws2)")
    ] = None,
    password_stdin: Annotated[
        bool, typer.Option("--password-stdin", help="read the password from stdin's first line")
    ] = False,
    password_prompt: Annotated[
        bool, typer.Option("--password-prompt", help="ask for the password, not echoed")
    ] = False,
    forget_password: Annotated[
        bool, typer.Option("--forget-password", help="remove the stored password")
    ] = False,
    timeout: Annotated[
        float | None, typer.Option(help="connect and read timeout, s (default 5)")
    ] = None,
    tls_verify: Annotated[
        bool, typer.Option(help="abb_rws2: check the controller's certificate")
    ] = True,
) -> None:
    """Set how the server reaches the robot's controller (admin scope). Without a password
    option a stored password is kept; --forget-password removes it."""
    secret = _password(password_stdin, password_prompt, forget_password)
    robot_id = resolve_robot(robot_ref)
    body: JsonObject = {"protocol": protocol, "host": host, "tls_verify": tls_verify}
    optional: JsonObject = {
        "port": port,
        "ports": _ports(ports) if ports else None,
        "username": user,
        "password": secret,
        "timeout_s": timeout,
    }
    body.update({name: value for name, value in optional.items() if value is not None})
    if forget_password:
        body["password"] = None  # null removes it; left out keeps it
    response = request("PUT", f"/v1/robots/{robot_id}/controller", json=body)
    if response.status_code >= 400:
        _refused(response)
    _show(robot_ref, response.json())


def connection(robot_ref: RobotArg) -> None:
    """Show how the server reaches the robot's controller."""
    robot_id = resolve_robot(robot_ref)
    response = request("GET", f"/v1/robots/{robot_id}/controller")
    if response.status_code >= 400:
        _refused(response)
    _show(robot_ref, response.json())


def disconnect(robot_ref: RobotArg) -> None:
    """Forget how the server reaches the robot's controller (admin scope); its deployments
    stay in the history."""
    robot_id = resolve_robot(robot_ref)
    response = request("DELETE", f"/v1/robots/{robot_id}/controller")
    if response.status_code >= 400:
        _refused(response)
    out.print(f"robot {robot_ref}: no controller connection", highlight=False)
