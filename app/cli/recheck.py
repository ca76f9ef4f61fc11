"""`tcpcal check TOOL --capture --reference NAME [--correct]`: the re-check after a collision
(issue 41). The robot stands with the TCP at a reference point; the server reads the flange
from the controller, checks the TCP against check_mm and, with --correct, corrects it within
the tool's max_correction_mm, activates and deploys it (POST /v1/tools/{id}/checks, the one
service the console and the MQTT command use too). This module only says the answer and
turns its verdict into an exit code a cell PC's script can branch on.
"""

from __future__ import annotations

from typing import NoReturn

import typer

from app.cli.bodies import CheckResult, Correction, Deployment, ReferencePoint
from app.cli.http import (
    EXIT_BAD_USE,
    EXIT_NOT_FOUND,
    err,
    fail,
    out,
    problem,
    refused,
    request,
    send,
)
from app.jsontypes import JsonObject

EXIT_IN_TOLERANCE = 0
EXIT_CORRECTED = 1
EXIT_CONTROLLER_FAILED = 3
#: Not 2: typer exits 2 for bad use (an unknown option, a missing argument), and a cell PC's
#: script must not read a typo as "recalibrate"; 4 to 6 are every command's (app.cli.http).
EXIT_RECALIBRATE = 7

#: The exit code of each verdict (the server's CheckResult.verdict). Out of tolerance without
#: --correct needs a person as much as a TCP beyond max_correction_mm does: 7.
VERDICT_EXITS = {
    "within_tolerance": EXIT_IN_TOLERANCE,
    "corrected": EXIT_CORRECTED,
    "out_of_tolerance": EXIT_RECALIBRATE,
    "recalibrate": EXIT_RECALIBRATE,
    "deployment_failed": EXIT_CONTROLLER_FAILED,
}

#: `check`'s help epilog: the two forms exit differently (3 meant out of tolerance before
#: --capture existed, and typed checks keep it).
CHECK_EXITS = (
    "Exit codes with --capture: 0 in tolerance; 1 corrected (the new version is active and, "
    "unless --no-deploy, on the controller and read back); 3 controller failure (the touch "
    "could not be read, or the correction is active in tcpcal but its deployment failed); 7 "
    "needs recalibration (beyond the tool's max_correction_mm, nothing changed; or out of "
    "tolerance without --correct). Typed poses: 0 in tolerance, 3 out of tolerance. Both: 4 "
    "refused (bad input, robot moving), 5 not found or not allowed, 6 server failed, 2 bad use."
)

#: What each deployment status means at the cell (as the console's tool page says them).
DEPLOYMENT_WORDS = {
    "verified": "verified: {target} holds version {version}, read back as written",
    "not_written": "not written: nothing was written, {target} still holds what it held",
    "unverified": "written, not confirmed: {target} may hold version {version} or what it "
    "held before; the next reconcile round will tell",
    "mismatch": "written, but {target} reads back otherwise: it does not hold version "
    "{version}; deploy again, or look on the pendant",
}

#: Problem kinds where the controller, not the request, failed.
_CONTROLLER_FAILURES = ("controller-unreachable", "controller-refused")


def reference_point_id(robot_id: str, ref: str) -> str:
    """The id of the robot's reference point `ref` names (its id or its name). Exit 5 naming
    the robot's points when none matches."""
    points: list[ReferencePoint] = []
    cursor = None
    while True:
        query = {"limit": "500", **({"cursor": cursor} if cursor else {})}
        page = send("GET", f"/v1/robots/{robot_id}/reference-points", params=query).json()
        points += page["items"]
        cursor = page["next_cursor"]
        if cursor is None:
            break
    for field in ("id", "name"):
        found = [p for p in points if p[field] == ref]
        if len(found) == 1:
            return found[0]["id"]
        if found:
            listed = ", ".join(p["id"] for p in found)
            fail(EXIT_BAD_USE, f"{len(found)} reference points are named {ref!r}: {listed}")
    known = ", ".join(p["name"] for p in points) or "none; POST one first"
    fail(EXIT_NOT_FOUND, f"the tool's robot has no reference point {ref!r} (it has: {known})")


def recheck(
    tool_id: str,
    reference: str,
    *,
    correct: bool,
    deploy: bool,
    reason: str | None,
    idempotency_key: str | None,
) -> NoReturn:
    """Capture one touch at the reference point, check and (when asked) correct; say the
    answer and exit with its code."""
    tool = send("GET", f"/v1/tools/{tool_id}").json()
    body: JsonObject = {
        "capture": True,
        "reference_point_id": reference_point_id(str(tool["robot_id"]), reference),
    }
    if correct:
        body["correct"] = "within_limits"
        if not deploy:
            body["deploy"] = False
    elif not deploy:
        fail(EXIT_BAD_USE, "--no-deploy applies to a correction: add --correct")
    if reason:
        body["reason"] = reason
    headers = {"Idempotency-Key": idempotency_key} if idempotency_key else {}
    response = request("POST", f"/v1/tools/{tool_id}/checks", json=body, headers=headers)
    if response.status_code >= 400:
        kind = str(problem(response).get("type", "")).rsplit("/", 1)[-1]
        if kind not in _CONTROLLER_FAILURES:
            refused(response)
        err.print(
            f"[bold red]{response.status_code}[/]: {problem(response).get('detail')}",
            highlight=False,
            soft_wrap=True,
        )
        raise typer.Exit(EXIT_CONTROLLER_FAILED)
    result: CheckResult = response.json()
    # the server's advice to redeploy names the HTTP call for an API client: say the command
    summary = result["summary"].replace(
        f"(POST /v1/tools/{tool_id}/deployments)", f"(tcpcal deploy {tool_id})"
    )
    out.print(summary, highlight=False, soft_wrap=True, markup=False)
    correction = result.get("correction")
    if correction:
        _say_correction(correction)
    raise typer.Exit(VERDICT_EXITS.get(result.get("verdict", ""), EXIT_RECALIBRATE))


def deployment_words(deployment: Deployment) -> str:
    """A deployment's status in words, with the controller's error when it failed."""
    words = DEPLOYMENT_WORDS.get(deployment["status"], deployment["status"])
    said = words.format(target=deployment["target"], version=deployment["version"])
    error = deployment.get("error")
    return f"{said} ({error['detail']})" if error else said


def _say_correction(correction: Correction) -> None:
    dx, dy, dz = correction["delta_mm"]
    length = (dx * dx + dy * dy + dz * dz) ** 0.5
    deployment = correction["deployment"]
    rows = [
        ("version", f"v{correction['version']} (was v{correction['previous_version']})"),
        ("delta", f"{dx:+.3f} {dy:+.3f} {dz:+.3f} mm ({length:.3f} mm, flange frame)"),
        ("deployment", "not deployed" if deployment is None else deployment_words(deployment)),
    ]
    for label, value in rows:
        out.print(f"  {label:<10}  {value}", highlight=False, soft_wrap=True)
