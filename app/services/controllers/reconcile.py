"""Reconcile a robot: read, over one connection, every live subject's frame (each subject
that declares a controller side: its tools, then the others) from its controller and compare
it with the subject's active version (in sync within 0.01 mm and 0.01 deg).

A robot whose protocol writes its one live one of a kind (a `live` scope, a protocol whose
declared address is a LiveTcp: contract v1.3) holds one at a time: the round judges the one
deployed to it last (in sync or drifted against its active version) and reports the others
of its kind `not_live`; when the controller cannot be reached, every one is `unreachable`, as
a stored-scope robot's.

As for deployments, the controller is read with no database transaction open; the states
found are then stored in one write transaction, each change of a state an audit event.
"""

from __future__ import annotations

import functools
from collections import namedtuple
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import bindparam, select
from sqlalchemy.orm import Session

from app.helpers.frame_deviation import (
    SYNC_TOLERANCE_DEG,
    SYNC_TOLERANCE_MM,
    frame_deviation,
    within,
)
from app.metrics import CONTROLLER_STATE_CHANGES, RECONCILES
from app.schemas.controllers import LiveToolMatch, Reconciliation
from app.security.auth import Principal, transaction_for
from app.services.controllers import settling
from app.services.controllers import states as controller_states
from app.services.controllers.deployments import side_of
from app.services.controllers.states import SEVERITY, Observation
from app.services.lifecycle.subject import AnySubject, Held
from app.services.robots.connection import (
    StoredController,
    get_controller,
    refusal_words,
    settings_of,
)
from app.services.robots.live_frame import record_live_frame
from app.services.robots.live_tool import LiveRead, live_tool_out, read_live, record_live
from app.services.subjects import SUBJECTS
from app.services.visible import robot_visible
from app.storage.db import HeldRead, session_scope
from app.storage.models import Robot, RobotController, utcnow
from app.vendors.connector import (
    Connector,
    ControllerError,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    FrameWriterMissing,
)
from app.vendors.registry import connect, scope_of
from app.vendors.registry import where as controller_address
from app.words import ROBOT_STATES, DeploymentScope, ProtocolName, RobotState, ToolState

#: Rounds a reconcile reads at most when a deployment to a robot with one live TCP keeps
#: changing which tool it judges while it reads (the last one stores what it read).
_ROUNDS = 3


@dataclass(frozen=True)
class ToCheck:
    """A live subject, where it lives in the controller and its active frame (if any)."""

    subject: AnySubject
    subject_id: str
    target: object  # None: the subject has no place in this controller
    target_name: str | None
    problem: str | None
    version: int | None
    position_mm: list[float] | None
    quaternion: list[float] | None

    @property
    def ref(self) -> tuple[str, str]:
        """The subject's kind and id: what its reading is found by."""
        return self.subject.kind, self.subject_id


@dataclass(frozen=True)
class Reading:
    """What the controller held for a subject, or why it could not be read; `unread`: no
    remote interface of the controller reads it (left out of the round, as one it cannot
    address, with `error` saying why)."""

    data: Held | None
    error: str | None
    unread: bool = False


#: Every subject reconciled with a controller, tools first.
DEPLOYED: tuple[AnySubject, ...] = tuple(s for s in SUBJECTS if s.controller is not None)


@functools.cache
def _to_check_read(subject: AnySubject) -> HeldRead[Any]:
    """The robot's live subjects of the kind with their active versions, oldest first: built
    once a kind (a round runs it for every robot; building and keying it cost more than its
    execution), the robot a bound parameter, on the driver's cursor (through Session.execute
    it was a sixth of the watcher's samples once the stores were), each row a named tuple of
    the subject's columns that the subject's controller side reads its target from."""
    table, versions = subject.table, subject.versions
    stmt = (
        select(
            table,
            versions.c.version.label("active_number"),
            versions.c.position_mm.label("active_position_mm"),
            versions.c.quaternion.label("active_quaternion"),
        )
        .outerjoin(
            versions,
            (subject.version_key() == table.c.id) & (versions.c.version == table.c.active_version),
        )
        .where(table.c.robot_id == bindparam("robot_id"), table.c.archived_at.is_(None))
        .order_by(table.c.created_at, table.c.id)
    )
    row = namedtuple(f"{subject.kind.title()}ToCheck", list(stmt.selected_columns.keys()))  # type: ignore[misc]
    return HeldRead(row, stmt)


def _to_check(
    session: Session, subject: AnySubject, robot_id: str, protocol: ProtocolName
) -> list[ToCheck]:
    side = side_of(subject)
    rows = _to_check_read(subject).all_in(session, robot_id=robot_id)
    found = []
    for row in rows:
        target = side.target(row)
        version = row.active_number
        problem = side.problem(protocol, target)
        found.append(
            ToCheck(
                subject=subject,
                subject_id=row.id,
                target=None if problem else target,
                target_name=None if problem else side.describe(protocol, target),
                problem=problem,
                version=version,
                position_mm=None if version is None else list(row.active_position_mm),
                quaternion=None if version is None else list(row.active_quaternion),
            )
        )
    return found


def read_controller(
    settings: ControllerSettings, checks: list[ToCheck], *, robot_id: str
) -> tuple[dict[tuple[str, str], Reading], LiveRead]:
    """Each addressable subject's frame as the controller holds it, then the tool the robot
    moves by (one session; no database). One the controller refuses to read is unreachable
    with its words; a connection that fails makes every one not yet read unreachable and
    the live tool unread."""
    readings: dict[tuple[str, str], Reading] = {}
    todo = [c for c in checks if c.target is not None]
    live = LiveRead(None, None)
    try:
        with connect(settings) as conn:
            for check in todo:
                readings[check.ref] = _read_one(conn, check, robot_id)
            live = read_live(conn)
    except (ControllerUnreachable, ControllerRefused, ControllerError) as exc:
        words = refusal_words(exc, robot_id) if isinstance(exc, ControllerRefused) else str(exc)
        where = controller_address(settings)
        for check in todo:
            readings.setdefault(check.ref, Reading(None, f"{where}: {words}"))
        live = LiveRead(None, f"{where}: {words}", reached=False)
    return readings, live


def _read_one(conn: Connector, check: ToCheck, robot_id: str) -> Reading:
    try:
        return Reading(side_of(check.subject).read(conn, check.target), None)
    except FrameWriterMissing as exc:
        return Reading(None, f"{exc.reason}; load {exc.file} by hand", unread=True)
    except ControllerRefused as exc:
        return Reading(None, f"refused: {refusal_words(exc, robot_id)}")


@dataclass(frozen=True)
class LiveScope:
    """Which one of a kind a round judges on a robot with one live one of that kind (a tool
    of a live-TCP robot): the one of the last deployment whose write may have reached it
    (None: none yet), and that deployment."""

    judged: str | None
    deployment_id: int | None

    def judges(self, subject_id: str) -> bool:
        return subject_id == self.judged


def live_scope(
    session: Session, subject: AnySubject, robot_id: str, scope: DeploymentScope
) -> LiveScope | None:
    """None for a robot whose controller stores each one of the kind (every one judged);
    else the one deployed to it last (a `not_written` attempt left the live one as it was)."""
    if scope != "live":
        return None
    table = subject.deployments
    assert table is not None
    row = session.execute(
        select(table.c.id, table.c[subject.key])
        .where(
            table.c.robot_id == robot_id,
            table.c.scope == "live",
            table.c.status != "not_written",
        )
        .order_by(table.c.id.desc())
        .limit(1)
    ).first()
    return LiveScope(None, None) if row is None else LiveScope(row[1], row[0])


def _live_scopes(
    session: Session, robot_id: str, protocol: ProtocolName
) -> dict[str, LiveScope | None]:
    """Each deployed subject's live scope on the robot, by kind."""
    return {s.kind: live_scope(session, s, robot_id, side_of(s).scope(protocol)) for s in DEPLOYED}


class _DeployedMeanwhile(Exception):
    """A deployment changed the one a live-scope robot's round judges while it read."""


def _observation(robot_id: str, check: ToCheck, reading: Reading) -> Observation:
    """The state of one subject from what the controller held."""
    held = reading.data
    deviation = None
    state: ToolState
    if held is None:
        state = "unreachable"
    elif check.version is None or check.position_mm is None or check.quaternion is None:
        state = "no_active_version"
    else:
        deviation = frame_deviation(
            check.position_mm, check.quaternion, held.position_mm, held.quaternion
        )
        ok = within(deviation, mm=SYNC_TOLERANCE_MM, deg=SYNC_TOLERANCE_DEG)
        state = "in_sync" if ok else "drifted"
    return Observation(
        subject=check.subject,
        subject_id=check.subject_id,
        robot_id=robot_id,
        state=state,
        target=check.target_name,
        controller=controller_states.frame_json(held),
        active_version=check.version,
        deviation_mm=None if deviation is None else deviation[0],
        deviation_deg=None if deviation is None else deviation[1],
        error=reading.error,
    )


@dataclass(frozen=True)
class RoundRead:
    """What one round read of a robot's controller (over one connection), before it is
    stored."""

    robot_id: str
    protocol: ProtocolName
    scope: DeploymentScope
    live_scopes: dict[str, LiveScope | None]
    checks: list[ToCheck]
    readings: dict[tuple[str, str], Reading]
    live: LiveRead
    read_from: datetime


#: Stores a round's read (and whether it is the last attempt); the watcher's batches.
StoreRound = Callable[[RoundRead, bool], "Reconciliation"]


def reconcile_robot(
    *,
    robot_id: str,
    actor: Principal,
    trigger: str = "api",
    cancelled: Callable[[], bool] = lambda: False,
    store: StoreRound | None = None,
) -> Reconciliation | None:
    """Read the robot's controller, compare with every live tool's active version, store
    the states; 404 for the robot, 409 when it has no controller. None when `cancelled()`
    turned true while the controller was read (a stopping watcher stores nothing). `store`
    stores the read (default: in a write transaction of its own; the watcher's stores
    several robots' reads in one)."""
    for attempt in range(_ROUNDS):
        read = _read_round(robot_id, actor)
        if cancelled():
            return None
        final = attempt == _ROUNDS - 1
        try:
            if store is not None:
                return store(read, final)
            return store_rounds([read], actor, trigger, final=[final])[0].result()
        except _DeployedMeanwhile:
            continue  # read again: the live TCP is another tool's now
    raise AssertionError("unreachable: the final round stores what it read")


def _read_round(robot_id: str, actor: Principal) -> RoundRead:
    """What to judge (read transaction), then the controller's values (no database)."""
    with transaction_for(actor, write=False) as session:
        controller = _controller(session, robot_id)
        settings = settings_of(controller)
        protocol = controller.protocol
        checks = [c for s in DEPLOYED for c in _to_check(session, s, robot_id, protocol)]
        judging = _live_scopes(session, robot_id, protocol)
    read_from = utcnow()
    judged = [c for c in checks if _judged(judging, c)]
    readings, live = read_controller(settings, judged, robot_id=robot_id)
    scope = scope_of(protocol)
    return RoundRead(robot_id, protocol, scope, judging, checks, readings, live, read_from)


def _controller(session: Session, robot_id: str) -> RobotController | StoredController:
    """The live robot's controller in one statement (a round reads every robot's, on the
    driver's cursor: through the ORM it was a sixth of the watcher's samples once the
    stores were off it), when the session's key may see the robot; else get_controller's
    answer: 404 for the robot, 409 for no controller."""
    found = _CONTROLLER.one_or_none_in(session, robot_id=robot_id)
    if found is not None and robot_visible(session, robot_id):
        return found
    return get_controller(session, robot_id)


#: The live robot's controller (built once: a round runs it for every robot).
_CONTROLLER = HeldRead(
    StoredController,
    select(*(RobotController.__table__.c[name] for name in StoredController._fields))
    .join(Robot, Robot.id == RobotController.robot_id)
    .where(RobotController.robot_id == bindparam("robot_id"), Robot.archived_at.is_(None)),
)


def _judged(judging: dict[str, LiveScope | None], check: ToCheck) -> bool:
    """Whether the round judges the subject against what the controller holds (every one
    but the ones of a live-scope kind not deployed last)."""
    scope = judging[check.subject.kind]
    return scope is None or scope.judges(check.subject_id)


@dataclass
class _Stored:
    """What storing one round wrote, for its answer once committed."""

    checked_at: datetime
    entered: list[ToolState]
    found: list[ToolState]
    #: each subject's answers by its plural ("tools"), and those left out by its
    #: `unaddressed` key ("not_addressable")
    answers: dict[str, list[dict[str, object]]]
    matches: list[LiveToolMatch]


class StoredRound:
    """A round's answer once stored, or the error storing it raised."""

    def __init__(self, answer: Reconciliation | None, error: BaseException | None) -> None:
        self._answer = answer
        self._error = error

    def result(self) -> Reconciliation:
        """The answer; raises what storing the round raised."""
        if self._error is not None:
            raise self._error
        assert self._answer is not None
        return self._answer


def store_rounds(
    reads: list[RoundRead], actor: Principal, trigger: str, *, final: list[bool]
) -> list[StoredRound]:
    """Store several robots' rounds in one write transaction (each robot's tool states and
    live tool together, as one round's); each one's answer or error. When any of them
    fails (a deployment meanwhile made another tool a live-TCP robot's live one, unless
    `final`), the transaction is rolled back and each is stored in a transaction of its
    own, so one robot's failure stores no other robot's round twice or not at all."""
    if len(reads) > 1:
        try:
            with transaction_for(actor, write=True) as session:  # the key's cells' robots
                stored = [
                    _write_round(session, read, actor, final=last)
                    for read, last in zip(reads, final, strict=True)
                ]
        except Exception:  # each is stored alone and says its own error
            return [
                store_rounds([read], actor, trigger, final=[last])[0]
                for read, last in zip(reads, final, strict=True)
            ]
        return [_answered(r, w, trigger) for r, w in zip(reads, stored, strict=True)]
    try:
        with transaction_for(actor, write=True) as session:
            one = _write_round(session, reads[0], actor, final=final[0])
    except Exception as exc:  # handed to the caller by result()
        return [StoredRound(None, exc)]
    return [_answered(reads[0], one, trigger)]


def _answered(read: RoundRead, stored: _Stored, trigger: str) -> StoredRound:
    """A stored round's answer, or the error building it raised: built after the commit,
    each in its own try, so one robot's failing answer is no other robot's error."""
    try:
        return StoredRound(_answer(read, stored, trigger), None)
    except Exception as exc:  # its round is stored; its reader hears what failed
        return StoredRound(None, exc)


def _write_round(session: Session, read: RoundRead, actor: Principal, *, final: bool) -> _Stored:
    """Write one round's states and live tool in the open write transaction.
    _DeployedMeanwhile (nothing written of it) when a deployment made another one a
    live-scope robot's live one while the round read, unless `final`."""
    robot_id = read.robot_id
    checked_at = utcnow()
    lists = [key for s in DEPLOYED for key in (s.plural, side_of(s).unaddressed)]
    stored = _Stored(checked_at, [], [], {key: [] for key in lists}, [])
    # first: it locks the robot's row before the subjects' (the order every writer keeps),
    # and the round's states and live tool commit together
    live = read.live
    stored.matches = record_live(session, robot_id=robot_id, live=live, at=checked_at, actor=actor)
    record_live_frame(session, robot_id=robot_id, live=live.frame, at=checked_at)
    if not final and read.live_scopes != _live_scopes(session, robot_id, read.protocol):
        raise _DeployedMeanwhile  # rolls the round back
    for check in read.checks:
        subject = check.subject
        reason = _left_out(check, read)
        if reason is not None:
            left_out: dict[str, object] = {subject.key: check.subject_id, "reason": reason}
            stored.answers[side_of(subject).unaddressed].append(left_out)
            continue
        seen = _seen(robot_id, check, read)
        since, changed = controller_states.observe(session, seen, at=checked_at, actor=actor)
        settling.settle(session, seen, read_from=read.read_from, at=checked_at, actor=actor)
        stored.found.append(seen.state)
        if changed:
            stored.entered.append(seen.state)
        stored.answers[subject.plural].append(_subject_answer(check, seen, since))
    return stored


def _answer(read: RoundRead, stored: _Stored, trigger: str) -> Reconciliation:
    """A stored round's answer, counted in /metrics."""
    for state in stored.entered:
        CONTROLLER_STATE_CHANGES.labels(state).inc()
    live = read.live
    robot_state = _robot_state(stored.found, reached=live.reached)
    RECONCILES.labels(trigger, robot_state).inc()
    return Reconciliation.model_validate(
        {
            "robot_id": read.robot_id,
            "checked_at": stored.checked_at,
            "state": robot_state,
            "scope": read.scope,
            **stored.answers,
            "live_tool": None if live.tool is None else live_tool_out(live.tool, stored.matches),
            "live_tool_error": live.error,
        }
    )


def _left_out(check: ToCheck, read: RoundRead) -> str | None:
    """Why the round leaves the subject out: it has no place in the controller, or no
    remote interface of the controller reads it; None when it is judged or not live."""
    if check.target is None:
        return check.problem
    reading = read.readings.get(check.ref)
    return reading.error if reading is not None and reading.unread else None


def _seen(robot_id: str, check: ToCheck, read: RoundRead) -> Observation:
    """The subject's state this round: judged from what the controller held, or `not_live`.
    A controller not reached makes every one unreachable, a live-scope robot's not judged
    too: nothing then says which one it moves by, and `not_live` would leave the fleet
    flagging no row of a robot nothing was deployed to yet."""
    if not _judged(read.live_scopes, check):
        if not read.live.reached:
            return _observation(robot_id, check, Reading(None, read.live.error))
        return controller_states.not_live(
            check.subject, check.subject_id, robot_id, check.target_name, check.version
        )
    return _observation(robot_id, check, read.readings[check.ref])


def _robot_state(found: list[ToolState], *, reached: bool) -> RobotState:
    """The worst of the tools' states; unreachable when the controller was not reached
    (also when no tool was judged: a live-TCP robot nothing was deployed to yet)."""
    worst = max((SEVERITY[state] for state in found), default=0)
    if not reached:
        worst = max(worst, SEVERITY["unreachable"])
    return ROBOT_STATES[worst]


def _subject_answer(check: ToCheck, seen: Observation, since: object) -> dict[str, object]:
    active = None
    if check.version is not None:
        active = {
            "version": check.version,
            "position_mm": check.position_mm,
            "quaternion": check.quaternion,
        }
    return {
        check.subject.key: check.subject_id,
        "target": check.target_name,
        "state": seen.state,
        "controller": seen.controller,
        "active": active,
        "deviation_mm": seen.deviation_mm,
        "deviation_deg": seen.deviation_deg,
        "since": since,
        "error": seen.error,
    }


def robots_with_controller() -> list[str]:
    """Ids of the live robots that have a controller (the watcher's round)."""
    with session_scope(write=False) as session:
        return list(
            session.scalars(
                select(RobotController.robot_id)
                .join(Robot, Robot.id == RobotController.robot_id)
                .where(Robot.archived_at.is_(None))
                .order_by(RobotController.robot_id)
            )
        )
