"""Reference points (fixed points in a robot's base frame) and laser devices, per robot."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.auth import Principal
from app.errors import Conflict
from app.models import ReferencePoint
from app.services import audit
from app.services.pagination import paginate
from app.services.registry import get_robot


def create_reference_point(
    session: Session,
    *,
    robot_id: str,
    name: str,
    position_mm: Sequence[float],
    covariance_mm2: Sequence[Sequence[float]] | None,
    source: str,
    calibration_id: str | None,
    actor: Principal,
) -> ReferencePoint:
    """Store a reference point (name unique per robot)."""
    get_robot(session, robot_id)
    taken = session.scalars(
        select(ReferencePoint.id).where(
            ReferencePoint.robot_id == robot_id, ReferencePoint.name == name
        )
    ).first()
    if taken:
        raise Conflict(
            f"robot {robot_id} already has a reference point named {name!r}",
            errors=[{"loc": ["body", "name"], "msg": "already taken"}],
        )
    row = ReferencePoint(
        robot_id=robot_id,
        name=name,
        position_mm=[float(v) for v in position_mm],
        covariance_mm2=[[float(v) for v in r] for r in covariance_mm2] if covariance_mm2 else None,
        source=source,
        calibration_id=calibration_id,
        created_by=actor.name,
    )
    session.add(row)
    session.flush()
    audit.record(
        session,
        actor=actor,
        action="reference_point.create",
        resource_type="reference_point",
        resource_id=row.id,
        robot_id=robot_id,
        details={"name": name, "source": source},
    )
    return row


def list_reference_points(
    session: Session,
    *,
    robot_id: str,
    limit: int,
    cursor: str | None,
) -> tuple[Sequence[ReferencePoint], str | None]:
    """A robot's reference points."""
    get_robot(session, robot_id)
    stmt = select(ReferencePoint).where(ReferencePoint.robot_id == robot_id)
    return paginate(
        session,
        stmt,
        created_col=ReferencePoint.created_at,
        id_col=ReferencePoint.id,
        limit=limit,
        cursor=cursor,
    )


def reference_point_out(row: ReferencePoint) -> dict[str, Any]:
    """Response document of a reference point."""
    return {
        "id": row.id,
        "robot_id": row.robot_id,
        "name": row.name,
        "position_mm": row.position_mm,
        "covariance_mm2": row.covariance_mm2,
        "source": row.source,
        "calibration_id": row.calibration_id,
        "created_at": row.created_at,
        "created_by": row.created_by,
    }
