"""The one domain error hierarchy: every layer raises these, the HTTP layer only maps them.

Pure Python (no web framework, no database, no pydantic), so the solvers, the kinematics
and the exports raise the same errors the services do. Each error has an HTTP status, a
machine-readable `kind` (the last segment of the problem type, e.g. "degenerate-poses"), a
sentence that says what went wrong and what to do, and where known the location of the
offending value in the request (`loc`).

`loc` convention: in an HTTP answer it always starts at the request root ("body", "query",
"path", "header"). Pure libraries do not know the request; they raise body-relative
locations (("poses", 3)) and the service that hands them the body roots them with
`located_in("body")`, in one place per use case.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Literal, get_args

Loc = tuple[str | int, ...]
#: Extension members of a problem document: JSON values only.
Extra = Mapping[str, object]


class DomainError(Exception):
    """An expected failure of a use case, with its HTTP status and problem kind."""

    status: int = 400
    kind: str = "bad-request"
    title: str = "Bad request"

    def __init__(
        self,
        detail: str,
        *,
        loc: Sequence[str | int] = (),
        msg: str | None = None,
        context: Extra | None = None,
        members: Extra | None = None,
        headers: Mapping[str, str] | None = None,
    ) -> None:
        super().__init__(detail)
        self.detail = detail
        self.loc: Loc = tuple(loc)
        #: what is wrong with the value at `loc`, in a few words (default: the detail)
        self.msg = msg or detail
        #: figures behind the failure (e.g. the predicted sigma): the problem's `context`
        self.context: dict[str, object] = dict(context or {})
        #: extension members that stand at the top of the problem document
        self.members: dict[str, object] = dict(members or {})
        self.headers: dict[str, str] = dict(headers or {})

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.kind!r}, {self.detail!r}, loc={self.loc!r})"

    def __reduce__(self) -> tuple[object, tuple[type[DomainError], dict[str, object]]]:
        """Picklable with every field, so an error raised in the solver pool
        (app.services.solve_pool) reaches the request as it was raised."""
        return _rebuild, (type(self), dict(self.__dict__))


def _rebuild(cls: type[DomainError], state: dict[str, object]) -> DomainError:
    error = cls.__new__(cls)
    Exception.__init__(error, state["detail"])
    error.__dict__.update(state)
    return error


class NotFound(DomainError):
    status, kind, title = 404, "not-found", "Not found"


class Archived(DomainError):
    status, kind, title = 404, "archived", "Archived"


class NoActiveVersion(DomainError):
    status, kind, title = 404, "no-active-version", "No active version"


class Conflict(DomainError):
    status, kind, title = 409, "conflict", "Conflict"


class NothingToDeploy(Conflict):
    """A deployment of a tool that has no active version (409, not the read's 404)."""

    kind, title = "no-active-version", "No active version"


class NoController(Conflict):
    kind, title = "no-controller", "Robot has no controller"


class RobotMoving(Conflict):
    """Two reads of a captured pose disagree: the robot was moving (nothing is kept)."""

    kind, title = "robot-moving", "Robot moving"


class NoControllerSet(NotFound):
    """GET of a robot's controller connection when none is set (404, contract v1.3)."""

    kind, title = "no-controller", "Robot has no controller"


class SecretUnreadable(Conflict):
    kind, title = "secret-unavailable", "Stored secret unreadable"


class ConnectorMissing(DomainError):
    """A stored controller whose protocol this tcpcal has no connector for (contract v1.3
    names protocols whose connectors land one by one): nothing is sent to it."""

    status, kind, title = 501, "no-connector", "No connector for the protocol"


class NoFrameWriter(DomainError):
    """A frame deployment to a controller no remote interface of which writes (or reads) the
    frame (contract v1.4 "Frames at the controller"): nothing is sent; `reason` says why and
    `file` what to load by hand."""

    status, kind, title = 501, "no-frame-writer", "No remote frame writer"


class ControllerUnreachableError(DomainError):
    status, kind, title = 502, "controller-unreachable", "Controller unreachable"


class ControllerRefusedError(DomainError):
    status, kind, title = 502, "controller-refused", "Controller refused"


class ControllerMismatch(DomainError):
    status, kind, title = 502, "controller-mismatch", "Controller holds something else"


class OutOfTolerance(DomainError):
    """Activating a version stored as out of tolerance without `force` and a reason."""

    status, kind, title = 409, "out-of-tolerance", "Version out of tolerance"


class NothingToRollBack(DomainError):
    """A rollback with no earlier activation to return to."""

    status, kind, title = 409, "nothing-to-roll-back", "Nothing to roll back"


class IdempotencyConflict(DomainError):
    status, kind, title = 409, "idempotency-key-reused", "Idempotency key reused"


class PreconditionFailed(DomainError):
    status, kind, title = 412, "precondition-failed", "Precondition failed"


class Unauthorized(DomainError):
    status, kind, title = 401, "unauthorized", "Unauthorized"


class Forbidden(DomainError):
    status, kind, title = 403, "forbidden", "Forbidden"


#: Every kind of unusable input (422): the last segment of its problem type. mypy checks
#: each `InvalidInput(kind, ...)` against this list.
InputKind = Literal[
    "validation",
    "too-few-poses",
    "repeated-poses",
    "degenerate-poses",
    "insufficient-spread",
    "invalid-rotation",
    "non-finite",
    "out-of-range",
    "invalid-pose",
    "invalid-options",
    "invalid-kinematics",
    "missing-kinematics",
    "orientation-changed",
    "invalid-direction",
    "invalid-sweep",
    "missing-load",
    "unknown-format",
    "unknown-reference",
    "needs-storage",
    "invalid-cursor",
    "invalid-interval",
    "unsupported",
    "convention-mismatch",
    "target-unreachable",
    "missing-secret-key",
    "controller-target",
    "invalid-host",
    "reason-required",
    "missing-role",
    "repeated-role",
    "collinear-points",
    "rigid-misfit",
]

#: The short title of each kind's problem document (every kind has one: checked below).
INPUT_TITLES: dict[InputKind, str] = {
    "validation": "Invalid request",
    "too-few-poses": "Too few poses",
    "repeated-poses": "Repeated poses",
    "degenerate-poses": "Degenerate poses",
    "insufficient-spread": "Orientation spread too small",
    "invalid-rotation": "Invalid rotation",
    "non-finite": "Non-finite value",
    "out-of-range": "Value out of range",
    "invalid-pose": "Invalid pose",
    "invalid-options": "Invalid options",
    "invalid-kinematics": "Invalid kinematics",
    "missing-kinematics": "Robot has no kinematics",
    "orientation-changed": "Orientation changed during a translation",
    "invalid-direction": "Invalid direction",
    "invalid-sweep": "Invalid laser sweep",
    "missing-load": "Tool load missing",
    "unknown-format": "Unknown format",
    "unknown-reference": "Unknown reference",
    "needs-storage": "Needs stored data",
    "invalid-cursor": "Invalid cursor",
    "invalid-interval": "Invalid time interval",
    "unsupported": "Not supported",
    "convention-mismatch": "Convention mismatch",
    "target-unreachable": "Target out of reach",
    "missing-secret-key": "Secret key not configured",
    "controller-target": "Tool has no place in its controller",
    "invalid-host": "Invalid host",
    "reason-required": "Reason required",
    "missing-role": "Touch role missing",
    "repeated-role": "Touch role repeated",
    "collinear-points": "Points on one line",
    "rigid-misfit": "Points do not fit a rigid body",
}
if set(INPUT_TITLES) != set(get_args(InputKind)):
    raise RuntimeError("INPUT_TITLES must title every InputKind, and only those")

#: The titles looked up by a plain string (a pydantic error type that may name a kind).
INPUT_KINDS: dict[str, str] = dict(INPUT_TITLES.items())


class InvalidInput(DomainError, ValueError):
    """Input that cannot be used (422), of one of the InputKind kinds."""

    status = 422
    kind: InputKind

    def __init__(
        self,
        kind: InputKind,
        detail: str,
        *,
        loc: Sequence[str | int] = (),
        context: Extra | None = None,
        members: Extra | None = None,
    ) -> None:
        if kind not in INPUT_TITLES:  # a kind mypy could not see (e.g. from a string)
            raise ValueError(f"unknown input error kind {kind!r}")
        super().__init__(detail, loc=loc, context=context, members=members)
        self.kind = kind
        self.title = INPUT_TITLES[kind]


@contextmanager
def located_in(*root: str | int) -> Iterator[None]:
    """Root the body-relative `loc` of input errors raised inside at `root` (e.g. "body")."""
    try:
        yield
    except InvalidInput as exc:
        exc.loc = (*root, *exc.loc)
        raise
