"""Reconcile a robot: read every live tool's frame from its controller and compare it with
the tool's active version (in sync within 0.01 mm and 0.01 deg).

A robot whose protocol writes its one live TCP (a `live` scope, UR and Techman: contract
v1.3) holds one tool at a time: the round judges the tool deployed to it last (in sync or
drifted against that tool's active version) and reports its other tools `not_live`; when
the controller cannot be reached, every tool is `unreachable`, as a stored-scope robot's.

As for deployments, the controller is read with no database transaction open; the states
found are then stored in one write transaction, each change of a tool's state an audit event.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import select
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
from app.services.controllers.states import SEVERITY, Observation
from app.services.robots.connection import get_controller, refusal_words, settings_of
from app.services.robots.live_tool import LiveRead, live_tool_out, read_live, record_live
from app.services.robots.robots import get_robot
from app.storage.db import session_scope
from app.storage.models import Deployment, Robot, RobotController, TcpVersion, Tool, utcnow
from app.vendors.connector import (
    ControllerError,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    ToolTarget,
)
from app.vendors.registry import connect, describe_target, scope_of, target_problem
from app.vendors.registry import where as controller_address
from app.vendors.tool import ToolData
from app.words import ROBOT_STATES, DeploymentScope, ProtocolName, RobotState, ToolState

#: Rounds a reconcile reads at most when a deployment to a robot with one live TCP keeps
#: changing which tool it judges while it reads (the last one stores what it read).
_ROUNDS = 3


@dataclass(frozen=True)
class ToolToCheck:
    """A live tool, where it lives in the controller and its active frame (if any)."""

    tool_id: str
    target: ToolTarget | None  # None: the tool has no place in this controller
    target_name: str | None
    problem: str | None
    version: int | None
    position_mm: list[float] | None
    quaternion: list[float] | None


@dataclass(frozen=True)
class Reading:
    """What the controller held for a tool, or why it could not be read."""

    data: ToolData | None
    error: str | None


def _tools_to_check(session: Session, robot_id: str, protocol: ProtocolName) -> list[ToolToCheck]:
    rows = session.execute(
        select(Tool.id, Tool.slot, Tool.controller_symbol, TcpVersion)
        .outerjoin(
            TcpVersion,
            (TcpVersion.tool_id == Tool.id) & (TcpVersion.version == Tool.active_version),
        )
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
        .order_by(Tool.created_at, Tool.id)
    )
    tools = []
    for tool_id, slot, symbol, version in rows:
        target = ToolTarget(slot=slot, symbol=symbol)
        problem = target_problem(protocol, target)
        tools.append(
            ToolToCheck(
                tool_id=tool_id,
                target=None if problem else target,
                target_name=None if problem else describe_target(protocol, target),
                problem=problem,
                version=None if version is None else version.version,
                position_mm=None if version is None else list(version.position_mm),
                quaternion=None if version is None else list(version.quaternion),
            )
        )
    return tools


def read_controller(
    settings: ControllerSettings, tools: list[ToolToCheck], *, robot_id: str
) -> tuple[dict[str, Reading], LiveRead]:
    """Each addressable tool's frame as the controller holds it, then the tool the robot
    moves by (one session; no database). A tool the controller refuses to read is
    unreachable with its words; a connection that fails makes every tool not yet read
    unreachable and the live tool unread."""
    readings: dict[str, Reading] = {}
    todo = [t for t in tools if t.target is not None]
    live = LiveRead(None, None)
    try:
        with connect(settings) as conn:
            for tool in todo:
                assert tool.target is not None
                try:
                    readings[tool.tool_id] = Reading(conn.read_tool(tool.target), None)
                except ControllerRefused as exc:
                    words = refusal_words(exc, robot_id)
                    readings[tool.tool_id] = Reading(None, f"refused: {words}")
            live = read_live(conn)
    except (ControllerUnreachable, ControllerRefused, ControllerError) as exc:
        words = refusal_words(exc, robot_id) if isinstance(exc, ControllerRefused) else str(exc)
        where = controller_address(settings)
        for tool in todo:
            readings.setdefault(tool.tool_id, Reading(None, f"{where}: {words}"))
        live = LiveRead(None, f"{where}: {words}", reached=False)
    return readings, live


@dataclass(frozen=True)
class LiveScope:
    """Which tool a round judges on a robot with one live TCP: the tool of the last
    deployment whose write may have reached it (None: none yet), and that deployment."""

    judged: str | None
    deployment_id: int | None

    def judges(self, tool_id: str) -> bool:
        return tool_id == self.judged


def live_scope(session: Session, robot_id: str, scope: DeploymentScope) -> LiveScope | None:
    """None for a robot whose controller stores each tool (every tool judged); else the
    tool deployed to it last (a `not_written` attempt left the live TCP as it was)."""
    if scope != "live":
        return None
    row = session.execute(
        select(Deployment.id, Deployment.tool_id)
        .where(
            Deployment.robot_id == robot_id,
            Deployment.scope == "live",
            Deployment.status != "not_written",
        )
        .order_by(Deployment.id.desc())
        .limit(1)
    ).first()
    return LiveScope(None, None) if row is None else LiveScope(row.tool_id, row.id)


class _DeployedMeanwhile(Exception):
    """A deployment changed the tool a live-TCP robot's round judges while it read."""


def _observation(robot_id: str, tool: ToolToCheck, reading: Reading) -> Observation:
    """The state of one tool from what the controller held."""
    held = reading.data
    deviation = None
    state: ToolState
    if held is None:
        state = "unreachable"
    elif tool.version is None or tool.position_mm is None or tool.quaternion is None:
        state = "no_active_version"
    else:
        deviation = frame_deviation(
            tool.position_mm, tool.quaternion, held.position_mm, held.quaternion
        )
        ok = within(deviation, mm=SYNC_TOLERANCE_MM, deg=SYNC_TOLERANCE_DEG)
        state = "in_sync" if ok else "drifted"
    return Observation(
        tool_id=tool.tool_id,
        robot_id=robot_id,
        state=state,
        target=tool.target_name,
        controller=controller_states.frame_json(held),
        active_version=tool.version,
        deviation_mm=None if deviation is None else deviation[0],
        deviation_deg=None if deviation is None else deviation[1],
        error=reading.error,
    )


@dataclass(frozen=True)
class RoundRead:
    """What one round read of a robot's controller (over one connection), before it is
    stored."""

    robot_id: str
    scope: DeploymentScope
    live_scope: LiveScope | None
    tools: list[ToolToCheck]
    readings: dict[str, Reading]
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
        get_robot(session, robot_id)
        controller = get_controller(session, robot_id)
        settings = settings_of(controller)
        tools = _tools_to_check(session, robot_id, controller.protocol)
        scope = scope_of(controller.protocol)
        judging = live_scope(session, robot_id, scope)
    read_from = utcnow()
    judged = [t for t in tools if judging is None or judging.judges(t.tool_id)]
    readings, live = read_controller(settings, judged, robot_id=robot_id)
    return RoundRead(robot_id, scope, judging, tools, readings, live, read_from)


@dataclass
class _Stored:
    """What storing one round wrote, for its answer once committed."""

    checked_at: datetime
    entered: list[ToolState]
    found: list[ToolState]
    answer_tools: list[dict[str, object]]
    skipped: list[dict[str, object]]
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
    """Write one round's tool states and live tool in the open write transaction.
    _DeployedMeanwhile (nothing written of it) when a deployment made another tool a
    live-TCP robot's live one while the round read, unless `final`."""
    robot_id = read.robot_id
    checked_at = utcnow()
    stored = _Stored(checked_at, [], [], [], [], [])
    # first: it locks the robot's row before the tools' (the order every writer keeps),
    # and the round's tool states and live tool commit together
    live = read.live
    stored.matches = record_live(session, robot_id=robot_id, live=live, at=checked_at, actor=actor)
    if not final and read.live_scope != live_scope(session, robot_id, read.scope):
        raise _DeployedMeanwhile  # rolls the round back
    for tool in read.tools:
        if tool.target is None:
            stored.skipped.append({"tool_id": tool.tool_id, "reason": tool.problem})
            continue
        seen = _seen(robot_id, tool, read)
        row, changed = controller_states.observe(session, seen, at=checked_at, actor=actor)
        settling.settle(session, seen, read_from=read.read_from, at=checked_at, actor=actor)
        stored.found.append(seen.state)
        if changed:
            stored.entered.append(seen.state)
        stored.answer_tools.append(_tool_answer(tool, seen, row.since))
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
            "tools": stored.answer_tools,
            "not_addressable": stored.skipped,
            "live_tool": None if live.tool is None else live_tool_out(live.tool, stored.matches),
            "live_tool_error": live.error,
        }
    )


def _seen(robot_id: str, tool: ToolToCheck, read: RoundRead) -> Observation:
    """The tool's state this round: judged from what the controller held, or `not_live`.
    A controller not reached makes every tool unreachable, a live-TCP robot's not judged
    too: nothing then says which tool it moves by, and `not_live` would leave the fleet
    flagging no row of a robot nothing was deployed to yet."""
    if read.live_scope is not None and not read.live_scope.judges(tool.tool_id):
        if not read.live.reached:
            return _observation(robot_id, tool, Reading(None, read.live.error))
        return controller_states.not_live(tool.tool_id, robot_id, tool.target_name, tool.version)
    return _observation(robot_id, tool, read.readings[tool.tool_id])


def _robot_state(found: list[ToolState], *, reached: bool) -> RobotState:
    """The worst of the tools' states; unreachable when the controller was not reached
    (also when no tool was judged: a live-TCP robot nothing was deployed to yet)."""
    worst = max((SEVERITY[state] for state in found), default=0)
    if not reached:
        worst = max(worst, SEVERITY["unreachable"])
    return ROBOT_STATES[worst]


def _tool_answer(tool: ToolToCheck, seen: Observation, since: object) -> dict[str, object]:
    active = None
    if tool.version is not None:
        active = {
            "version": tool.version,
            "position_mm": tool.position_mm,
            "quaternion": tool.quaternion,
        }
    return {
        "tool_id": tool.tool_id,
        "target": tool.target_name,
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
