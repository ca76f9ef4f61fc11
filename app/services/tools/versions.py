"""TCP versions: numbering, activation (with history), and serving the active TCP."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import NamedTuple

from sqlalchemy import BindParameter, Engine, bindparam, insert, select, update
from sqlalchemy.orm import Session

from app.config import get_settings
from app.errors import InvalidInput, NoActiveVersion, NotFound
from app.helpers.etags import if_none_match_hit
from app.jsontypes import JsonObject
from app.schemas.tools import ActiveTcp, Tcp, ToolTable, Version
from app.security.auth import Principal, cells_of
from app.services.audit import writes as audit
from app.services.robots.robots import get_robot
from app.services.tools.controller_text import ServedTool, ServedVersion, controller_text
from app.services.tools.drift import StoredDrift, fit_drift, refresh_drift, stored
from app.services.tools.hot_read import active_of, read_for_key
from app.services.tools.tools import get_tool
from app.services.visible import live_or_404
from app.storage.db import DriverWrite, HeldRead
from app.storage.models import Activation, Robot, TcpVersion, Tool, new_id, table_of, utcnow
from app.words import (
    FORMATS_IN_WORDS,
    ActivationKind,
    AuditAction,
    ControllerFormat,
    MethodName,
    Status,
)

IDENTITY_QUATERNION = [1.0, 0.0, 0.0, 0.0]


# ---- the writes: numbering and activation under the tool's lock ------------------------------
# Core statements on the session's connection, not ORM objects: a calibration writes a version,
# the tool's counters and two audit events, and the unit of work's pass over them cost more
# than the statements (store 5 -> 1.6 ms in process). ORM objects of the same rows, where a
# caller holds one, are expired after each write so that they read it back.
_TOOL = table_of(Tool)
_VERSION = table_of(TcpVersion)
_ROBOT = table_of(Robot)


class _LockRow(NamedTuple):
    """A row of _LOCK_TOOL."""

    id: str
    robot_id: str
    name: str
    archived_at: datetime | None
    tolerance: JsonObject
    active_version: int | None
    last_version: int
    revision: int
    kinematics: JsonObject | None
    cell: str | None


_LOCK_TOOL = HeldRead(
    _LockRow,
    select(
        _TOOL.c.id,
        _TOOL.c.robot_id,
        _TOOL.c.name,
        _TOOL.c.archived_at,
        _TOOL.c.tolerance,
        _TOOL.c.active_version,
        _TOOL.c.last_version,
        _TOOL.c.revision,
        _ROBOT.c.kinematics,
        _ROBOT.c.cell,
    )
    .join(_ROBOT, _ROBOT.c.id == _TOOL.c.robot_id)
    .where(_TOOL.c.id == bindparam("tool_id"))
    .with_for_update(of=_TOOL),
)
#: The tool's counters as its writes set them (`_counters` gives their values).
_COUNTERS: dict[str, BindParameter[object]] = {
    name: bindparam(name) for name in ("active_version", "last_version", "revision", "updated_at")
}
_SAVE_TOOL = DriverWrite(
    update(_TOOL).where(_TOOL.c.id == bindparam("tool_id")).values(**_COUNTERS)
)
#: The counters and the drift trend in one statement (`save_deferred`).
_SAVE_TOOL_AND_DRIFT = DriverWrite(
    update(_TOOL)
    .where(_TOOL.c.id == bindparam("tool_id"))
    .values(**_COUNTERS, **{name: bindparam(name) for name in StoredDrift._fields})
)
_INSERT_VERSION = DriverWrite(insert(_VERSION))
_INSERT_ACTIVATION = DriverWrite(insert(table_of(Activation)))


@dataclass(slots=True)
class LockedTool:
    """A live tool read under its row lock (FOR UPDATE; BEGIN IMMEDIATE on SQLite), with its
    robot's model: what numbering and activating versions read and change."""

    id: str
    robot_id: str
    name: str
    tolerance: JsonObject | None
    active_version: int | None
    last_version: int
    revision: int
    kinematics: JsonObject | None
    #: When a deferred write (add_version or activate with `deferred`) changed the counters.
    updated_at: datetime | None = None

    @property
    def next_version(self) -> int:
        """The number the tool's next version gets."""
        return self.last_version + 1


def lock_tool(session: Session, tool_id: str) -> LockedTool:
    """Lock a live tool's row for the rest of the transaction (serialises its versions), or
    404. Pending ORM changes are written first, so that the lock reads them."""
    session.flush()
    row = _LOCK_TOOL.one_or_none_in(session, tool_id=tool_id)
    cells = cells_of(session)
    if row is not None and cells is not None and row.cell not in cells:
        row = None  # a tool of another cell's robot: as if absent
    row = live_or_404(row, "tool", tool_id)
    return LockedTool(
        row.id,
        row.robot_id,
        row.name,
        row.tolerance,
        row.active_version,
        row.last_version,
        row.revision,
        row.kinematics,
    )


def _save(session: Session, tool: LockedTool, now: datetime) -> None:
    """Write the locked tool's counters; an ORM copy of the row reads them back when next used."""
    _SAVE_TOOL.execute(session, [_counters(tool, now)])
    _expire(session, tool)


def _counters(tool: LockedTool, now: datetime) -> dict[str, object]:
    return {
        "tool_id": tool.id,
        "active_version": tool.active_version,
        "last_version": tool.last_version,
        "revision": tool.revision,
        "updated_at": now,
    }


def _expire(session: Session, tool: LockedTool) -> None:
    cached = session.identity_map.get(session.identity_key(Tool, tool.id))
    if cached is not None:
        session.expire(cached)


def save_deferred(session: Session, tool: LockedTool) -> None:
    """Write what deferred writes changed: the tool's counters and its drift trend, refitted
    once for them all, in one UPDATE (a calibration's version and its activation each wrote
    the row, and each refitted a trend that the next one replaced)."""
    if tool.updated_at is None:
        return
    drift = fit_drift(
        session, tool_id=tool.id, active_version=tool.active_version, tolerance=tool.tolerance
    )
    row = {**_counters(tool, tool.updated_at), **stored(drift)._asdict()}
    _SAVE_TOOL_AND_DRIFT.execute(session, [row])
    tool.updated_at = None
    _expire(session, tool)


def add_version(
    session: Session,
    *,
    tool: LockedTool,
    position_mm: Sequence[float],
    quaternion: Sequence[float],
    source: MethodName,
    status: Status,
    calibration_id: str | None,
    note: str | None,
    actor: Principal,
    created_at: datetime | None = None,
    deferred: bool = False,
) -> int:
    """Append version n+1 of a tool locked with `lock_tool`; its number. `created_at`: the
    time of the calibration it comes from (default now). The tool's counters and its drift
    trend are written now, or with `deferred` by the caller's `save_deferred` once it has
    written everything of the transaction."""
    now = created_at or utcnow()
    tool.last_version = tool.next_version
    tool.revision += 1
    _INSERT_VERSION.execute(
        session,
        [
            {
                "id": new_id(),
                "tool_id": tool.id,
                "version": tool.last_version,
                "position_mm": [float(v) for v in position_mm],
                "quaternion": [float(v) for v in quaternion],
                "source": source,
                "status": status,
                "calibration_id": calibration_id,
                "note": note,
                "created_at": now,
                "created_by": actor.name,
            }
        ],
    )
    if deferred:
        tool.updated_at = now
    else:
        _save(session, tool, now)
    audit.record(
        session,
        actor=actor,
        action="version.create",
        resource_type="tool",
        resource_id=tool.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        version=tool.last_version,
        details={"source": source, "status": status},
    )
    if not deferred:
        _refresh_drift(session, tool)
    return tool.last_version


def activate(
    session: Session,
    *,
    tool: LockedTool,
    version: int,
    reason: ActivationKind,
    actor: Principal,
    reason_text: str | None = None,
    action: AuditAction = "version.activate",
    details: JsonObject | None = None,
    deferred: bool = False,
) -> None:
    """Make `version` the active one and record who did it, when and why (a tool locked with
    `lock_tool`). `reason` is the kind (explicit, forced, rollback, calibration:auto, ...),
    `reason_text` the person's own words; both go into the activation history. The audit
    event (`action`, with `details` added) carries the kind as `kind` and the why as
    `reason`: the person's words when given, else the kind. `deferred`: the counters and
    the drift trend are written by the caller's `save_deferred`."""
    now = utcnow()
    previous, tool.active_version = tool.active_version, version
    tool.revision += 1
    _INSERT_ACTIVATION.execute(
        session,
        [
            {
                "tool_id": tool.id,
                "version": version,
                "previous_version": previous,
                "reason": reason,
                "reason_text": reason_text,
                "activated_by": actor.name,
                "activated_at": now,
            }
        ],
    )
    if deferred:
        tool.updated_at = now
    else:
        _save(session, tool, now)
    event: JsonObject = {
        "version": version,
        "previous_version": previous,
        "kind": reason,
        "reason": reason if reason_text is None else reason_text,
    }
    audit.record(
        session,
        actor=actor,
        action=action,
        resource_type="tool",
        resource_id=tool.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        version=version,
        details={**event, **(details or {})},
    )
    if not deferred:
        _refresh_drift(session, tool)


def _refresh_drift(session: Session, tool: LockedTool) -> None:
    """The tool's drift trend after a new version or activation (a new version is a new point
    of the TCP's series; another active version, another reference and set of checks)."""
    refresh_drift(
        session, tool_id=tool.id, active_version=tool.active_version, tolerance=tool.tolerance
    )


def get_version(session: Session, *, tool_id: str, version: int) -> TcpVersion:
    """One version of a live tool, or 404."""
    get_tool(session, tool_id)
    row = session.scalars(
        select(TcpVersion).where(TcpVersion.tool_id == tool_id, TcpVersion.version == version)
    ).one_or_none()
    if row is None:
        raise NotFound(f"tool {tool_id} has no version {version}")
    return row


def list_versions(
    session: Session, *, tool_id: str
) -> tuple[Tool, list[TcpVersion], list[Activation]]:
    """Every version of a tool (oldest first) and its activation history."""
    tool = get_tool(session, tool_id)
    versions = list(
        session.scalars(
            select(TcpVersion).where(TcpVersion.tool_id == tool_id).order_by(TcpVersion.version)
        )
    )
    history = list(
        session.scalars(
            select(Activation).where(Activation.tool_id == tool_id).order_by(Activation.id)
        )
    )
    return tool, versions, history


def active_version_row(session: Session, tool: Tool) -> TcpVersion:
    """The active version of a tool, or 404 /no-active-version."""
    if tool.active_version is None:
        raise NoActiveVersion(f"tool {tool.id} ({tool.name}) has no active TCP version yet")
    return session.scalars(
        select(TcpVersion).where(
            TcpVersion.tool_id == tool.id, TcpVersion.version == tool.active_version
        )
    ).one()


def tcp_etag(
    tool: ServedTool, row: ServedVersion, fmt: ControllerFormat | None, as_text: bool = False
) -> str:
    """Strong ETag of what /tcp serves: the numbers, slot, load and the representation
    (the JSON document or the controller text alone)."""
    payload = json.dumps(
        [
            tool.id,
            tool.slot,
            tool.name,
            tool.load,
            row.version,
            row.position_mm,
            row.quaternion,
            fmt,
            as_text,
        ],
        sort_keys=True,
    )
    return '"' + hashlib.sha256(payload.encode()).hexdigest()[:32] + '"'


def version_document(row: TcpVersion, tool: Tool) -> Version:
    """A version as the API shows it."""
    return Version(
        version=row.version,
        tcp=Tcp(position_mm=row.position_mm, quaternion=row.quaternion),
        source=row.source,
        status=row.status,
        calibration_id=row.calibration_id,
        note=row.note,
        created_at=row.created_at,
        created_by=row.created_by,
        active=tool.active_version == row.version,
    )


def active_document(
    tool: ServedTool, row: ServedVersion, fmt: ControllerFormat | None
) -> ActiveTcp:
    """What a cell controller reads: the active TCP, and its controller text when asked."""
    return ActiveTcp(
        tool_id=tool.id,
        robot_id=tool.robot_id,
        tool_name=tool.name,
        slot=tool.slot,
        version=row.version,
        tcp=Tcp(position_mm=row.position_mm, quaternion=row.quaternion),
        calibrated_at=row.created_at,
        method=row.source,
        controller=None if fmt is None else controller_text(fmt, tool=tool, version=row),
    )


def _text_needs_format(as_text: bool, fmt: ControllerFormat | None) -> None:
    if as_text and fmt is None:
        raise InvalidInput(
            "invalid-options",
            "Accept: text/plain serves a controller's text: give ?format= "
            f"({FORMATS_IN_WORDS}), or accept application/json",
            loc=("query", "format"),
        )


def served_tcp(
    session: Session,
    *,
    tool_id: str,
    fmt: ControllerFormat | None,
    if_none_match: str | None,
    as_text: bool = False,
) -> tuple[ActiveTcp | None, str]:
    """(document, ETag) of a tool's active TCP; document None when the client's copy is current.
    `as_text`: the controller text alone will be served (its own ETag)."""
    _text_needs_format(as_text, fmt)
    tool = get_tool(session, tool_id)
    row = active_version_row(session, tool)
    etag = tcp_etag(tool, row, fmt, as_text)
    if if_none_match_hit(if_none_match, etag):
        return None, etag
    return active_document(tool, row, fmt), etag


def tool_table(session: Session, *, robot_id: str, fmt: ControllerFormat | None) -> ToolTable:
    """Every live tool's active TCP. A tool the format cannot express (no slot for KUKA, no
    load for ABB) carries its own controller_error instead of failing the whole table."""
    get_robot(session, robot_id)
    tools = session.scalars(
        select(Tool)
        .where(Tool.robot_id == robot_id, Tool.archived_at.is_(None))
        .order_by(Tool.slot, Tool.name)
    ).all()
    items: list[ActiveTcp] = []
    missing: list[str] = []
    for tool in tools:
        if tool.active_version is None:
            missing.append(tool.id)
            continue
        row = active_version_row(session, tool)
        try:
            items.append(active_document(tool, row, fmt))
        except InvalidInput as exc:
            item = active_document(tool, row, None)
            item.controller_error = {
                "type": get_settings().problem_type(exc.kind),
                "detail": exc.detail,
            }
            items.append(item)
    return ToolTable(robot_id=robot_id, items=items, without_active_version=missing)


def served_tcp_for_key(
    engine: Engine,
    *,
    authorization: str | None,
    tool_id: str,
    fmt: ControllerFormat | None,
    if_none_match: str | None,
    as_text: bool = False,
) -> tuple[Principal, ActiveTcp | None, str]:
    """`served_tcp` for the caller behind `authorization`: the key check, the tool and its
    active version in one statement (app.services.tools.hot_read): (who, document or None when the
    client's copy is current, ETag)."""
    principal, found = read_for_key(engine, authorization, tool_id)
    _text_needs_format(as_text, fmt)
    tool, row = active_of(found, principal, tool_id)
    etag = tcp_etag(tool, row, fmt, as_text)
    if if_none_match_hit(if_none_match, etag):
        return principal, None, etag
    return principal, active_document(tool, row, fmt), etag
