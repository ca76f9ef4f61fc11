"""A connector's failure as the 502 problem a client gets (contract v1.3), written once for
every request that talks to a controller: a capture's still reads and a deployment.

Each sentence says what happened, where (the controller's address), and ends with what the
attempt left (`left`: "nothing was kept" for a capture, the deployment's status words). The
one difference between the two callers is on purpose and a parameter (`refusal`): what a
refusal says after the controller's own words.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

from app.errors import (
    ControllerRefusedError,
    ControllerUnreachableError,
    DomainError,
    NoFrameWriter,
)
from app.services.robots.connection import refusal_words
from app.vendors.connector import (
    ControllerCredentialsRefused,
    ControllerError,
    ControllerRefused,
    ControllerSettings,
    ControllerSilent,
    ControllerUnreachable,
    FrameWriterMissing,
)
from app.vendors.registry import where as controller_address

#: What a refusal says besides the controller's own words. `remedy`: those words and what a
#: person can do about them (a deployment, whose status words then say what the controller
#: holds). `connector`: the connector's sentence after them, for it says why and what to do
#: (a capture: a controller's external-TCP mode, move with the tool on the flange) where the
#: controller's words alone do not.
RefusalWords = Literal["remedy", "connector"]


def controller_problem(
    exc: ControllerError,
    settings: ControllerSettings,
    *,
    robot_id: str,
    left: str,
    refusal: RefusalWords,
    sent: bool = False,
    members: Mapping[str, object] | None = None,
) -> DomainError:
    """The 502 for `exc`: /controller-refused with the controller's words as
    `controller_message`, else /controller-unreachable (unreachable, or an answer not in its
    protocol); the 501 /no-frame-writer for a frame no remote interface of the controller
    writes, with its `reason` and the `file` to load by hand. `sent`: the write had been
    sent, so an unreachable controller stopped answering after it; `members`: the caller's
    own (a deployment's status)."""
    where = controller_address(settings)
    told = dict(members or {})
    if isinstance(exc, FrameWriterMissing):
        told |= {"reason": exc.reason, "file": exc.file}
        return NoFrameWriter(
            f"tcpcal cannot write this frame into the {settings.protocol} controller at "
            f"{where}: {exc.reason}; load {exc.file} by hand instead (nothing was sent); "
            f"{left}",
            members=told,
        )
    if isinstance(exc, ControllerRefused):
        told["controller_message"] = exc.controller_message
        return ControllerRefusedError(f"{_refused(exc, robot_id, refusal)}; {left}", members=told)
    if isinstance(exc, ControllerSilent) and not sent:
        return ControllerUnreachableError(
            f"the controller at {where} did not answer: {exc}. Something answered the port "
            "(the TCP connection was accepted) and sent nothing back: check that the robot's "
            f"controller speaks {settings.protocol} and that the port is its "
            f"{settings.protocol} port (another maker's controller, or another of its "
            "services, accepts and stays silent so; set the protocol and port with "
            f"PUT /v1/robots/{robot_id}/controller, or "
            f"tcpcal connect ROBOT --protocol P --port N); {left}",
            members=told,
        )
    if isinstance(exc, ControllerUnreachable):
        happened = (
            "stopped answering after the write was sent"
            if sent
            else f"could not be reached within {settings.timeout_s:g} s"
        )
        return ControllerUnreachableError(
            f"the controller at {where} {happened}: {exc}; {left}", members=told
        )
    return ControllerUnreachableError(
        f"the controller at {where} answered something that is not its protocol: {exc}; {left}",
        members=told,
    )


def _refused(exc: ControllerRefused, robot_id: str, refusal: RefusalWords) -> str:
    if refusal == "remedy":
        return f"the controller refused: {refusal_words(exc, robot_id)}"
    # Refused credentials: which user, and the request that sets the password (as the
    # remedy says), rather than the connector's HTTP 401.
    why = str(exc)
    if isinstance(exc, ControllerCredentialsRefused):
        why = refusal_words(exc, robot_id)
    return f"the controller refused ({exc.controller_message}): {why}"
