"""Deploy a subject's active version to its robot's controller (any declared subject with a
controller side: app.services.lifecycle.subject.ControllerSide): write it, read it back,
compare, and record the attempt whatever became of it.

Three steps, and no database transaction is open during the controller's I/O (which may
take up to the controller's timeout): 1. a read transaction gathers what to write and where;
2. the connector writes and reads back; 3. a write transaction records the attempt (and,
when verified, that the controller holds the active version). Runs in a worker thread: the
connectors are blocking I/O with a deadline.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Protocol, cast

from pydantic import BaseModel
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import (
    ControllerMismatch,
    ControllerUnreachableError,
    DomainError,
    InvalidInput,
    NothingToDeploy,
)
from app.helpers.frame_deviation import (
    DEPLOY_TOLERANCE_DEG,
    DEPLOY_TOLERANCE_MM,
    frame_deviation,
    within,
)
from app.helpers.pagination import paginate_newest_first
from app.jsontypes import JsonObject
from app.metrics import DEPLOYMENTS
from app.security.auth import Principal, transaction_for
from app.services import idempotency
from app.services.audit import writes as audit
from app.services.controllers import states as controller_states
from app.services.controllers.failures import controller_problem
from app.services.controllers.states import StateRow
from app.services.lifecycle.subject import AnySide, AnySubject, Held
from app.services.lifecycle.versions import get_live
from app.services.robots.connection import get_controller, settings_of
from app.services.robots.live_tool import LiveRead, record_live
from app.storage.models import Base, Robot, utcnow
from app.vendors.connector import (
    Connector,
    ControllerError,
    ControllerRefused,
    ControllerSettings,
    Frame,
    LiveTool,
)
from app.vendors.registry import connect
from app.words import DeploymentStatus, FailedDeploymentStatus, ProtocolName

#: How long a repeated key waits for the first request's deployment to end: a deployment
#: ends within its controller's timeout_s (at most 60 s, app.schemas.controllers) and the
#: session's clean-up. Past it (the first request's process ended mid-deployment) the answer
#: kept before the deployment is replayed, and the reconcile rounds settle the controller.
DEPLOYMENT_WAIT_S = 65.0


@dataclass(frozen=True)
class Plan:
    """What to write where, read in one transaction before any I/O."""

    subject: AnySubject
    subject_id: str
    robot_id: str
    version: int
    target: object
    target_name: str
    data: Held
    settings: ControllerSettings
    #: the version the controller held in sync at the last look, if another one
    held_version: int | None = None

    @property
    def side(self) -> AnySide:
        return side_of(self.subject)


@dataclass(frozen=True)
class Outcome:
    """What the controller did with it."""

    status: DeploymentStatus
    previous: Held | None = None
    read_back: Held | None = None
    deviation: tuple[float, float] | None = None
    error: DomainError | None = None
    controller_message: str | None = None


def side_of(subject: AnySubject) -> AnySide:
    """The subject's controller side; it is deployed only when it declares one."""
    side = subject.controller
    assert side is not None, f"the {subject.kind} declares no controller side"
    return side


def subject_target(subject: AnySubject, protocol: ProtocolName, row: object) -> object:
    """Where the subject (its row) lives in its controller; 422 naming the subject's field
    to set."""
    side = side_of(subject)
    target = side.target(row)
    problem = side.problem(protocol, target)
    if problem is not None:
        field = side.field(protocol)
        raise InvalidInput(
            "controller-target",
            f"{problem} (PATCH {subject.path}/{{{subject.key}}} with {field!r})",
            members={"field": field},
        )
    return target


def plan_deployment(session: Session, subject: AnySubject, subject_id: str) -> Plan:
    """What deploying the subject now means; 409 without an active version or a
    controller, 422 when the subject has no place in the controller."""
    row = get_live(session, subject, subject_id)
    if row.active_version is None:
        raise NothingToDeploy(
            f"{subject.kind} {subject_id} has no active version to deploy: activate a version first"
        )
    controller = get_controller(session, row.robot_id)
    target = subject_target(subject, controller.protocol, row)
    version = session.scalars(
        select(subject.version_model).where(
            subject.version_key() == row.id, subject.versions.c.version == row.active_version
        )
    ).one()
    state = cast(StateRow | None, session.get(_model(subject.state_model), row.id))
    held_version = None
    if state is not None and state.state == "in_sync" and state.active_version != version.version:
        held_version = state.active_version
    return Plan(
        subject=subject,
        subject_id=row.id,
        robot_id=row.robot_id,
        version=version.version,
        target=target,
        target_name=side_of(subject).describe(controller.protocol, target),
        data=side_of(subject).held(row, version),
        settings=settings_of(controller),
        held_version=held_version,
    )


def _model(model: type[Base] | None) -> type[Base]:
    assert model is not None, "a deployed subject declares its controller tables"
    return model


class DeploymentRow(Protocol):
    """What is read of a deployment's ORM row (a models.Deployment)."""

    id: int
    robot_id: str
    version: int
    protocol: str
    target: str
    scope: str
    status: str
    previous: JsonObject | None
    read_back: JsonObject | None
    deviation_mm: float | None
    deviation_deg: float | None
    error: JsonObject | None
    reason: str | None
    settled: JsonObject | None
    actor: str
    created_at: datetime


@dataclass
class _Attempt:
    """How far an attempt got: what was read before, whether the write may have reached
    the controller, what was read after."""

    previous: Held | None = None
    sent: bool = False
    read_back: Held | None = None


def write_and_read_back(plan: Plan) -> Outcome:
    """Write the plan into the controller and read it back (no database here). A failure
    is `not_written` when it came before the write was sent, `unverified` after."""
    attempt = _Attempt()
    try:
        with connect(plan.settings) as conn:
            attempt.previous = plan.side.read(conn, plan.target)
            _write(conn, plan, attempt)
            attempt.read_back = plan.side.read(conn, plan.target)
    except ControllerError as exc:
        return _failure(plan, attempt, exc)
    read_back = attempt.read_back
    data = plan.data
    deviation = frame_deviation(
        data.position_mm, data.quaternion, read_back.position_mm, read_back.quaternion
    )
    if within(deviation, mm=DEPLOY_TOLERANCE_MM, deg=DEPLOY_TOLERANCE_DEG):
        return Outcome("verified", attempt.previous, read_back, deviation)
    error = ControllerMismatch(
        f"{plan.target_name} reads back {deviation[0]:.4f} mm and {deviation[1]:.4f} deg "
        f"from what was written (allowed {DEPLOY_TOLERANCE_MM} mm, {DEPLOY_TOLERANCE_DEG} deg)",
        members={"deployment_status": "mismatch"},
    )
    return Outcome("mismatch", attempt.previous, read_back, deviation, error=error)


def _write(conn: Connector, plan: Plan, attempt: _Attempt) -> None:
    """Write, noting whether the write may have reached the controller. A refusal after
    the write was sent (the controller still answers) is followed by one read: the
    controller may show it kept what it held."""
    try:
        plan.side.write(conn, plan.target, plan.data)
    except ControllerRefused as exc:
        attempt.sent = exc.write_sent
        if exc.write_sent:
            with contextlib.suppress(ControllerError):
                attempt.read_back = plan.side.read(conn, plan.target)
        raise
    except ControllerError as exc:
        attempt.sent = exc.write_sent
        raise
    attempt.sent = True


def _same_frame(a: Held, b: Held) -> bool:
    deviation = frame_deviation(a.position_mm, a.quaternion, b.position_mm, b.quaternion)
    return within(deviation, mm=DEPLOY_TOLERANCE_MM, deg=DEPLOY_TOLERANCE_DEG)


def _failure_status(plan: Plan, attempt: _Attempt) -> FailedDeploymentStatus:
    """not_written when the write never left, or the controller refused it and still shows
    what it held; unverified otherwise (it may hold either frame)."""
    if not attempt.sent:
        return "not_written"
    held, before = attempt.read_back, attempt.previous
    if (
        held is not None
        and before is not None
        and _same_frame(held, before)
        and not _same_frame(held, plan.data)
    ):
        return "not_written"
    return "unverified"


def status_words(status: FailedDeploymentStatus, version: int, held_version: int | None) -> str:
    """What a deployment that failed short of a read-back leaves on the controller, in the
    words of the person at the cell."""
    if status == "not_written":
        return "nothing was written: the controller still holds what it held"
    before = "what it held before" if held_version is None else f"v{held_version}"
    return (
        f"written, not confirmed: the controller may hold v{version} or {before}; "
        "the next reconcile round will tell"
    )


def _failure(plan: Plan, attempt: _Attempt, exc: ControllerError) -> Outcome:
    status = _failure_status(plan, attempt)
    error = controller_problem(
        exc,
        plan.settings,
        robot_id=plan.robot_id,
        left=status_words(status, plan.version, plan.held_version),
        refusal="remedy",
        sent=attempt.sent,
        members={"deployment_status": status},
    )
    message = exc.controller_message if isinstance(exc, ControllerRefused) else None
    return Outcome(
        status,
        attempt.previous,
        attempt.read_back,
        error=error,
        controller_message=message,
    )


def deploy(
    subject: AnySubject,
    *,
    subject_id: str,
    actor: Principal,
    idempotency_key: str | None,
    raw_body: JsonObject,
    reason: str | None = None,
) -> tuple[JsonObject, bool]:
    """Deploy the subject's active version: (the deployment, whether it is a replay). A
    failed or mismatched attempt is recorded and then raised as its 502 with
    `deployment_id`."""
    fingerprint = idempotency.request_fingerprint(f"deploy:{subject_id}", raw_body)
    if idempotency_key is not None:
        with transaction_for(actor, write=False) as session:
            replayed = idempotency.replay(
                session, actor=actor, key=idempotency_key, fingerprint=fingerprint, purge=False
            )
        if replayed is not None:
            return replayed, True

    def keep(session: Session, document: JsonObject) -> None:
        if idempotency_key is not None:
            idempotency.remember(
                session,
                actor=actor,
                key=idempotency_key,
                fingerprint=fingerprint,
                response=document,
            )

    done = attempt(subject, subject_id=subject_id, actor=actor, reason=reason, keep=keep)
    if done.error is not None:
        raise done.error
    return done.document.model_dump(mode="json"), False


@dataclass(frozen=True)
class Attempt:
    """A recorded deployment as served (the subject's deployment schema), and its failure
    (None when verified) as the 502 a client gets, `deployment_id` and `deployment_status`
    among its members."""

    document: BaseModel
    error: DomainError | None
    subject: AnySubject
    subject_id: str
    robot_id: str
    at: datetime


def attempt(
    subject: AnySubject,
    *,
    subject_id: str,
    actor: Principal,
    reason: str | None,
    keep: Callable[[Session, JsonObject], None] | None = None,
) -> Attempt:
    """Deploy the subject's active version and record the attempt whatever became of it;
    refusals before any I/O (no active version, controller or address) are raised.
    `keep`: called with the verified deployment's document in the transaction recording it
    (an Idempotency-Key's answer)."""
    with transaction_for(actor, write=False) as session:
        plan = plan_deployment(session, subject, subject_id)
    outcome = write_and_read_back(plan)
    with transaction_for(actor, write=True) as session:
        row = _record(session, plan, outcome, actor, reason)
        document = deployment_document(subject, row)
        if keep is not None and outcome.status == "verified":
            keep(session, document.model_dump(mode="json"))
    DEPLOYMENTS.labels(plan.settings.protocol, outcome.status).inc()
    if outcome.error is not None:
        outcome.error.members["deployment_id"] = str(row.id)
    return Attempt(
        document,
        outcome.error,
        subject=subject,
        subject_id=plan.subject_id,
        robot_id=plan.robot_id,
        at=row.created_at,
    )


def flag_failed(session: Session, attempt: Attempt, actor: Principal) -> None:
    """The subject's controller state after a failed deployment of the version a re-check
    just activated (a tool's or a frame's, one definition): the controller does not hold it
    (drifted), or could not be reached (unreachable)."""
    error = attempt.error
    assert error is not None
    document = attempt.document.model_dump(mode="json")
    held = document.get("read_back") or document.get("previous")
    controller_states.observe(
        session,
        controller_states.Observation(
            subject=attempt.subject,
            subject_id=attempt.subject_id,
            robot_id=attempt.robot_id,
            state="unreachable" if isinstance(error, ControllerUnreachableError) else "drifted",
            target=cast(str | None, document.get("target")),
            controller=cast(JsonObject | None, held),
            active_version=cast(int, document["version"]),
            deviation_mm=None,
            deviation_deg=None,
            error=error.detail,
        ),
        at=attempt.at,
        actor=actor,
    )


def _record(
    session: Session, plan: Plan, outcome: Outcome, actor: Principal, reason: str | None
) -> DeploymentRow:
    """The attempt, its audit event and, when verified, the subject's state in sync."""
    error = None
    if outcome.error is not None:
        error = {
            "type": outcome.error.kind,
            "detail": outcome.error.detail,
            "controller_message": outcome.controller_message,
        }
    dev_mm, dev_deg = outcome.deviation if outcome.deviation is not None else (None, None)
    subject = plan.subject
    new = _model(subject.deployment_model)(
        **{subject.key: plan.subject_id},
        robot_id=plan.robot_id,
        version=plan.version,
        protocol=plan.settings.protocol,
        target=plan.target_name,
        status=outcome.status,
        scope=plan.side.scope(plan.settings.protocol),
        previous=controller_states.frame_json(outcome.previous),
        read_back=controller_states.frame_json(outcome.read_back),
        deviation_mm=dev_mm,
        deviation_deg=dev_deg,
        error=error,
        reason=reason,
        actor=actor.name,
        created_at=utcnow(),
    )
    row = cast(DeploymentRow, new)
    audit.add_created(
        session,
        row,
        actor=actor,
        action=plan.side.deploy_action,
        resource_type="deployment",
        robot_id=plan.robot_id,
        about={subject.key: plan.subject_id},
        details={
            "status": outcome.status,
            "version": plan.version,
            "protocol": plan.settings.protocol,
            "target": plan.target_name,
            "scope": row.scope,
            "previous": row.previous,
            "error": error,
            "reason": reason,
        },
    )
    if row.scope == "live" and plan.side.moved_by:
        _record_live_tcp(session, plan, outcome, row, actor)
    if outcome.status == "verified":
        _in_sync(session, plan, outcome, row, actor)
    return row


def _in_sync(
    session: Session, plan: Plan, outcome: Outcome, row: DeploymentRow, actor: Principal
) -> None:
    """A verified deployment's subject is in sync; on a `live` scope robot, its other ones of
    the kind are not live from then on."""
    controller_states.observe(
        session,
        controller_states.Observation(
            subject=plan.subject,
            subject_id=plan.subject_id,
            robot_id=plan.robot_id,
            state="in_sync",
            target=plan.target_name,
            controller=controller_states.frame_json(outcome.read_back),
            active_version=plan.version,
            deviation_mm=row.deviation_mm,
            deviation_deg=row.deviation_deg,
            error=None,
        ),
        at=row.created_at,
        actor=actor,
    )
    if row.scope == "live":
        controller_states.others_not_live(
            session,
            subject=plan.subject,
            robot_id=plan.robot_id,
            live_id=plan.subject_id,
            target=plan.target_name,
            at=row.created_at,
            actor=actor,
        )


def _record_live_tcp(
    session: Session, plan: Plan, outcome: Outcome, row: DeploymentRow, actor: Principal
) -> None:
    """The robot's one live TCP as the deployment left it (`live_after`); the robot's row is
    locked first, as every writer of its tools' states locks it."""
    session.execute(select(Robot.id).where(Robot.id == plan.robot_id).with_for_update())
    live = live_after(outcome)
    if live is not None:
        record_live(session, robot_id=plan.robot_id, live=live, at=row.created_at, actor=actor)


#: Why a robot's one live TCP is not known after a deployment wrote it and read nothing back.
LIVE_UNCONFIRMED = (
    "a deployment's write was sent and not read back: the robot may move by the version "
    "written or by what it held; the next reconcile round will tell"
)


def live_after(outcome: Outcome) -> LiveRead | None:
    """What a deployment to a robot's one live TCP (a `live` scope, its protocol's address a
    LiveTcp: the tool read and written is the TCP the robot moves by) last read of it: the
    read-back, else what it held before a write that was never sent; unread when a write was
    sent and nothing was read after it. None when nothing was read and nothing changed (the
    round's read stands). A stored-scope controller's read-back says nothing of which tool
    the robot moves by."""
    held = outcome.read_back
    if held is None and outcome.status == "not_written":
        held = outcome.previous
        if held is None:
            return None
    if held is None:
        return LiveRead(None, LIVE_UNCONFIRMED)
    return LiveRead(LiveTool(number=None, frame=Frame(held.position_mm, held.quaternion)), None)


def deployment_document(subject: AnySubject, row: DeploymentRow) -> BaseModel:
    """A deployment as served (the subject's deployment schema)."""
    return side_of(subject).deployment_schema.model_validate(
        {
            "id": str(row.id),
            subject.key: getattr(row, subject.key),
            "robot_id": row.robot_id,
            "version": row.version,
            "protocol": row.protocol,
            "target": row.target,
            "scope": row.scope,
            "status": row.status,
            "previous": row.previous,
            "read_back": row.read_back,
            "deviation_mm": row.deviation_mm,
            "deviation_deg": row.deviation_deg,
            "error": row.error,
            "reason": row.reason,
            "settled": row.settled,
            "actor": row.actor,
            "created_at": row.created_at,
        }
    )


def list_deployments(
    session: Session, subject: AnySubject, *, subject_id: str, limit: int, cursor: str | None
) -> tuple[Sequence[BaseModel], str | None]:
    """A subject's deployments, newest first."""
    found = get_live(session, subject, subject_id)
    model = _model(subject.deployment_model)
    stmt = select(model).where(getattr(model, subject.key) == found.id)
    rows, next_cursor = paginate_newest_first(
        session,
        stmt,
        id_col=getattr(model, "id"),  # noqa: B009 (a model of any subject)
        limit=limit,
        cursor=cursor,
    )
    return [deployment_document(subject, cast(DeploymentRow, r)) for r in rows], next_cursor
