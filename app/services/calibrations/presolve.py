"""A calibration solved before its write transaction: what the solve reads of the database
(the snapshot, read in one statement on the held connection, no session, no lock) and the
solve against it, which the write keeps unless the snapshot has changed under the lock."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple

from sqlalchemy import Engine, and_, bindparam, select

from app.errors import InvalidInput
from app.helpers.tolerance import effective_tolerance
from app.jsontypes import JsonArray, JsonObject
from app.methods.base import MethodRequest
from app.security.auth import Principal
from app.services.calibrations.contexts import SnapshotContext
from app.services.calibrations.grading import Outcome, solve
from app.services.touches.tool_frames import frame_from
from app.services.visible import live_or_404
from app.storage.db import HeldRead
from app.storage.models import Calibration as CalibrationRow
from app.storage.models import Robot, TcpVersion, Tool, table_of


@dataclass(frozen=True)
class Snapshot:
    """What a calibration's solve reads from the database: equal snapshots, equal results."""

    tolerance: JsonObject | None
    active_version: int | None
    kinematics: JsonObject | None


@dataclass(frozen=True)
class Presolved:
    """A calibration solved before its transaction, with what the solve read."""

    snapshot: Snapshot
    outcome: Outcome


class SnapshotRow(NamedTuple):
    """A row of SNAPSHOT_READ: the tool, its robot's model and cell, and its active version
    with its calibration's result (None when it has no active version, or the version no
    calibration)."""

    name: str
    archived_at: datetime | None
    tolerance: JsonObject
    active_version: int | None
    kinematics: JsonObject | None
    cell: str | None
    version: int | None
    position_mm: JsonArray | None
    quaternion: JsonArray | None
    result: JsonObject | None


_TOOL, _ROBOT = table_of(Tool), table_of(Robot)
_VERSION, _CALIBRATION = table_of(TcpVersion), table_of(CalibrationRow)
#: What a calibration's solve reads, as one statement on the event loop's held connection
#: (app.storage.db.HeldRead): the tool, its robot's model, its active version and the covariance
#: its calibration reported. Read in a worker thread through a session, the same took three
#: ORM queries and a thread hop (2 ms of the server's one core per calibration).
SNAPSHOT_READ = HeldRead(
    SnapshotRow,
    select(
        _TOOL.c.name,
        _TOOL.c.archived_at,
        _TOOL.c.tolerance,
        _TOOL.c.active_version,
        _ROBOT.c.kinematics,
        _ROBOT.c.cell,
        _VERSION.c.version,
        _VERSION.c.position_mm,
        _VERSION.c.quaternion,
        _CALIBRATION.c.result,
    )
    .select_from(_TOOL)
    .join(_ROBOT, _ROBOT.c.id == _TOOL.c.robot_id)
    .outerjoin(
        _VERSION,
        and_(_VERSION.c.tool_id == _TOOL.c.id, _VERSION.c.version == _TOOL.c.active_version),
    )
    .outerjoin(_CALIBRATION, _CALIBRATION.c.id == _VERSION.c.calibration_id)
    .where(_TOOL.c.id == bindparam("tool_id")),
)


def snapshot_held(
    engine: Engine, tool_id: str, actor: Principal | None = None
) -> tuple[Snapshot, SnapshotContext]:
    """What a calibration of this tool will solve against (no lock, no session): the
    snapshot the write compares under the lock, and the solver's context. A tool of a robot
    outside the actor's cells is not found."""
    row = SNAPSHOT_READ.one_or_none(engine, tool_id=tool_id)
    if row is not None and actor is not None and not actor.sees_cell(row.cell):
        row = None
    row = live_or_404(row, "tool", tool_id)
    frame = None
    if row.version is not None:  # a version's columns are never NULL
        assert row.position_mm is not None
        assert row.quaternion is not None
        frame = frame_from(row.position_mm, row.quaternion, row.version, row.result)
    snapshot = Snapshot(row.tolerance, row.active_version, row.kinematics)
    return snapshot, SnapshotContext(row.kinematics, effective_tolerance(row.tolerance), frame)


def solve_snapshot(request: MethodRequest, ctx: SnapshotContext) -> Outcome | None:
    """Solve against a snapshot (in a solver process); None when the method needs to look
    up more stored data (reference points, other tools, laser devices): solve it in place."""
    try:
        return solve(request, ctx)
    except InvalidInput as refusal:
        if refusal.kind == "needs-storage":
            return None
        raise
