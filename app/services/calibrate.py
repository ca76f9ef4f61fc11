"""Submitting a calibration: solve, grade, version, activate, store, all in one transaction.

Nothing is written before the solver succeeds, so unsolvable input (a 422) leaves no row.
The tool row is locked first (SELECT ... FOR UPDATE; BEGIN IMMEDIATE on SQLite), which
serialises version numbering and makes idempotency-key replays see the first response.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from datetime import timedelta
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from app.auth import Principal
from app.config import get_settings
from app.errors import IdempotencyConflict, InvalidInput, NotFound
from app.methods import run_method
from app.methods.base import ActiveFrame, SolvedTcp, StoredPoint
from app.models import (
    Calibration,
    IdempotencyRecord,
    LaserDevice,
    ReferencePoint,
    Robot,
    Tool,
    utcnow,
)
from app.schemas.calibrations import Calibration as CalibrationOut
from app.schemas.common import Units
from app.services import audit
from app.services.frames import active_frame, parse_poses_with
from app.services.kinematics import validate_kinematics
from app.services.pagination import paginate
from app.services.references import create_reference_point
from app.services.registry import get_robot, get_tool
from app.services.tolerance import effective_tolerance, grade
from app.services.versions import IDENTITY_QUATERNION, activate, add_version


# ---- contexts -------------------------------------------------------------------------------
class DbContext:
    """Method context backed by the database, for one tool of one robot."""

    def __init__(self, session: Session, tool: Tool, robot: Robot) -> None:
        self.session, self.tool, self.robot = session, tool, robot

    @property
    def tolerance(self) -> dict[str, Any]:
        return effective_tolerance(self.tool.tolerance)

    def active_frame(self) -> ActiveFrame | None:
        return active_frame(self.session, self.tool)

    def parse_poses(
        self, fmt: str, poses: Sequence[Any], units: Units | None, *, loc: Sequence[str | int]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return parse_poses_with(self.robot.kinematics, fmt, poses, units, loc=loc)

    def reference_point(self, reference_point_id: str) -> StoredPoint:
        row = self.session.get(ReferencePoint, reference_point_id)
        if row is None or row.robot_id != self.robot.id:
            raise InvalidInput(
                "unknown-reference",
                f"robot {self.robot.id} has no reference point {reference_point_id}",
                loc=("body", "options", "reference_point_id"),
            )
        cov = np.asarray(row.covariance_mm2, dtype=float) if row.covariance_mm2 else None
        return StoredPoint(np.asarray(row.position_mm, dtype=float), cov)

    def tool_frame(self, tool_id: str) -> ActiveFrame:
        other = self.session.get(Tool, tool_id)
        if other is None or other.archived_at is not None or other.robot_id != self.robot.id:
            raise InvalidInput(
                "unknown-reference",
                f"robot {self.robot.id} has no live tool {tool_id}",
                loc=("body", "options", "reference_tool_id"),
            )
        frame = active_frame(self.session, other)
        if frame is None:
            raise InvalidInput(
                "unknown-reference",
                f"reference tool {tool_id} has no active TCP to trust",
                loc=("body", "options", "reference_tool_id"),
            )
        return frame

    def laser_device(self, device_id: str) -> tuple[float, float, float]:
        row = self.session.get(LaserDevice, device_id)
        if row is None or row.robot_id != self.robot.id:
            raise InvalidInput(
                "unknown-reference",
                f"robot {self.robot.id} has no laser device {device_id}",
                loc=("body", "laser", "device_id"),
            )
        return row.beam_a_y_mm, row.beam_b_x_mm, row.plane_z_mm


class StatelessContext:
    """Method context for POST /v1/solve: nothing stored is read except an optional robot."""

    def __init__(self, kinematics: dict[str, Any] | None, tolerance: dict[str, Any] | None) -> None:
        self._kinematics = kinematics
        self._tolerance = effective_tolerance(
            {k: v for k, v in (tolerance or {}).items() if v is not None}
        )

    @property
    def tolerance(self) -> dict[str, Any]:
        return self._tolerance

    def active_frame(self) -> ActiveFrame | None:
        return None

    def parse_poses(
        self, fmt: str, poses: Sequence[Any], units: Units | None, *, loc: Sequence[str | int]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return parse_poses_with(self._kinematics, fmt, poses, units, loc=loc)

    def _stored(self, what: str, field: tuple[str, ...], instead: str) -> InvalidInput:
        return InvalidInput(
            "needs-storage",
            f"/v1/solve stores nothing and cannot look up {what}; {instead}",
            loc=("body", *field),
        )

    def reference_point(self, reference_point_id: str) -> StoredPoint:
        raise self._stored(
            "a reference point",
            ("options", "reference_point_id"),
            "give options.reference_point_mm",
        )

    def tool_frame(self, tool_id: str) -> ActiveFrame:
        raise self._stored(
            "another tool's TCP",
            ("options", "reference_tool_id"),
            "give options.reference_point_mm",
        )

    def laser_device(self, device_id: str) -> tuple[float, float, float]:
        raise self._stored(
            "a laser device", ("laser", "device_id"), "give beam_a_y_mm, beam_b_x_mm and plane_z_mm"
        )


# ---- results --------------------------------------------------------------------------------
def result_document(
    request: Any,
    solved: SolvedTcp,
    ctx: DbContext | StatelessContext,
) -> dict[str, Any]:
    """The CalibrationResult of a solve, graded against the tolerance in the context."""
    status, reasons = grade(solved.quality, ctx.tolerance, graded=solved.graded)
    quaternion = solved.quaternion
    warnings = list(solved.warnings) + reasons
    if quaternion is None:
        frame = ctx.active_frame()
        if frame is not None:
            quaternion = frame.quaternion
            warnings.append(
                f"orientation kept from active version {frame.version}: "
                f"{request.method} calibrates the position only"
            )
        else:
            quaternion = np.asarray(IDENTITY_QUATERNION)
    doc: dict[str, Any] = {
        "method": request.method,
        "algorithm": solved.algorithm,
        "status": status,
        "tcp": {
            "position_mm": [float(v) for v in solved.position_mm],
            "quaternion": [float(v) for v in quaternion],
        },
        "reference_point_mm": solved.reference_point_mm,
        "quality": solved.quality,
        "warnings": warnings,
        "details": {},
    }
    for key, value in solved.extra.items():
        doc[key] = value
    return doc


def _calibration_out(row: Calibration, tool: Tool) -> dict[str, Any]:
    return {
        **row.result,
        "id": row.id,
        "tool_id": row.tool_id,
        "version": row.version,
        "active": row.version is not None and tool.active_version == row.version,
        "created_at": row.created_at,
        "created_by": row.created_by,
    }


# ---- idempotency ----------------------------------------------------------------------------
def request_fingerprint(tool_id: str, raw_body: dict[str, Any]) -> str:
    """Hash of what a retry must repeat exactly: the target and the body."""
    canonical = json.dumps([tool_id, raw_body], sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def _replay(
    session: Session,
    *,
    actor: Principal,
    key: str,
    fingerprint: str,
) -> dict[str, Any] | None:
    ttl = timedelta(hours=get_settings().idempotency_ttl_hours)
    session.execute(delete(IdempotencyRecord).where(IdempotencyRecord.created_at < utcnow() - ttl))
    record = session.scalars(
        select(IdempotencyRecord).where(
            IdempotencyRecord.api_key_id == actor.key_id, IdempotencyRecord.key == key
        )
    ).one_or_none()
    if record is None:
        return None
    if record.request_hash != fingerprint:
        raise IdempotencyConflict(
            f"Idempotency-Key {key!r} was already used with a different request body or tool; "
            "use a new key for a new submission"
        )
    return record.response


# ---- use cases ------------------------------------------------------------------------------
def submit(
    session: Session,
    *,
    tool_id: str,
    request: Any,
    raw_body: dict[str, Any],
    idempotency_key: str | None,
    actor: Principal,
) -> tuple[dict[str, Any], bool]:
    """Solve and store a calibration; (Calibration document, replayed?)."""
    tool = get_tool(session, tool_id, for_update=True)
    fingerprint = request_fingerprint(tool_id, raw_body)
    if idempotency_key is not None:
        replay = _replay(session, actor=actor, key=idempotency_key, fingerprint=fingerprint)
        if replay is not None:
            return replay, True

    robot = get_robot(session, tool.robot_id)
    ctx = DbContext(session, tool, robot)
    solved = run_method(request, ctx)  # SolveError -> 422 before anything is written
    doc = result_document(request, solved, ctx)

    row = Calibration(
        tool_id=tool.id,
        method=request.method,
        algorithm=solved.algorithm,
        status=doc["status"],
        request=raw_body,
        result=doc,
        created_by=actor.name,
    )
    session.add(row)
    session.flush()
    version = add_version(
        session,
        tool=tool,
        position_mm=doc["tcp"]["position_mm"],
        quaternion=doc["tcp"]["quaternion"],
        source=request.method,
        status=doc["status"],
        calibration_id=row.id,
        note=request.note,
        actor=actor,
    )
    row.version = version.version
    should_activate = request.activate == "always" or (
        request.activate == "auto" and doc["status"] == "accepted"
    )
    if should_activate:
        activate(
            session,
            tool=tool,
            version=version.version,
            reason=f"calibration:{request.activate}",
            actor=actor,
        )
    _save_reference_point(
        session,
        request=request,
        solved=solved,
        status=doc["status"],
        tool=tool,
        calibration=row,
        actor=actor,
    )
    audit.record(
        session,
        actor=actor,
        action="calibration.create",
        resource_type="calibration",
        resource_id=row.id,
        robot_id=tool.robot_id,
        tool_id=tool.id,
        details={
            "method": request.method,
            "status": doc["status"],
            "version": version.version,
            "activated": should_activate,
        },
    )
    out = _calibration_out(row, tool)
    if idempotency_key is not None:
        session.add(
            IdempotencyRecord(
                api_key_id=actor.key_id,
                key=idempotency_key,
                request_hash=fingerprint,
                status_code=201,
                response=CalibrationOut.model_validate(out).model_dump(mode="json"),
            )
        )
        session.flush()
    return out, False


def _save_reference_point(
    session: Session,
    *,
    request: Any,
    solved: SolvedTcp,
    status: str,
    tool: Tool,
    calibration: Calibration,
    actor: Principal,
) -> None:
    name = getattr(getattr(request, "options", None), "save_reference_point", None)
    if name is None or solved.reference_point_mm is None:
        return
    if status != "accepted":
        solved.warnings.append(
            f"reference point {name!r} not saved: the calibration is out of tolerance"
        )
        return
    create_reference_point(
        session,
        robot_id=tool.robot_id,
        name=name,
        position_mm=solved.reference_point_mm,
        covariance_mm2=solved.reference_covariance_mm2,
        source="xyz_npoint",
        calibration_id=calibration.id,
        actor=actor,
    )


def solve_stateless(session: Session, *, request: Any) -> dict[str, Any]:
    """Solve without storing anything (POST /v1/solve)."""
    kinematics: dict[str, Any] | None = None
    if request.kinematics is not None:
        kinematics = validate_kinematics(request.kinematics)
    elif request.robot_id is not None:
        kinematics = get_robot(session, request.robot_id).kinematics
    ctx = StatelessContext(kinematics, request.tolerance)
    solved = run_method(request, ctx)
    return result_document(request, solved, ctx)


def list_calibrations(
    session: Session,
    *,
    tool_id: str,
    limit: int,
    cursor: str | None,
) -> tuple[list[dict[str, Any]], str | None]:
    """A tool's calibrations, oldest first."""
    tool = get_tool(session, tool_id)
    rows, next_cursor = paginate(
        session,
        select(Calibration).where(Calibration.tool_id == tool_id),
        created_col=Calibration.created_at,
        id_col=Calibration.id,
        limit=limit,
        cursor=cursor,
    )
    return [_calibration_out(r, tool) for r in rows], next_cursor


def get_calibration(session: Session, *, calibration_id: str) -> dict[str, Any]:
    """One calibration with the submission as received."""
    row = session.get(Calibration, calibration_id)
    if row is None:
        raise NotFound(f"no calibration with id {calibration_id}")
    tool = session.get(Tool, row.tool_id)
    assert tool is not None
    return {**_calibration_out(row, tool), "request": row.request}
