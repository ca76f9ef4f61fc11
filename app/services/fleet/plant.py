"""What the plant is shown of each live subject (the OPC UA address space's values: every
tool, every frame of app.services.subjects): its robot and name, the active version's value
(also as kuka_abc), its status and how it went live (the activation's kind and reason), the
controller's state, and when it last changed.

Read through the fleet service (names, active version, controller state: one judge of
those), one query for the active versions' values, statuses and the subjects' change times,
and one for the latest activations (app.services.lifecycle.published, which the MQTT
sink's retained message reads too).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime

from sqlalchemy import and_, select
from sqlalchemy.orm import Session

from app.kinematics.poses import kuka_abc_from_matrix, matrix_from_quaternion_wxyz
from app.services.fleet.fleet import FleetRow
from app.services.fleet.gauges import all_rows, controller_state
from app.services.lifecycle.published import LastActivation, active_statuses, last_activations
from app.services.lifecycle.subject import AnySubject
from app.services.subjects import IN_FLEET, Served
from app.storage.models import Robot

__all__ = ["LastActivation", "PlantItem", "PlantRobot", "plant_items", "plant_robots"]

Vector = tuple[float, ...]


@dataclass(frozen=True)
class PlantItem:
    """One live subject (a tool, a frame) as the plant sees it; the value's fields are None
    with no active version, `status` (the active version's: accepted or out_of_tolerance) and
    `activation` too."""

    subject_id: str
    robot_id: str
    robot_name: str
    name: str
    active_version: int | None
    position_mm: Vector | None
    quaternion: Vector | None
    kuka_abc: Vector | None
    controller_state: str
    updated_at: datetime
    status: str | None = None
    activation: LastActivation | None = None


@dataclass(frozen=True)
class PlantRobot:
    """One live robot and its live subjects, by subject kind ("tool": its tools, oldest
    first); a kind it has none of may be left out."""

    robot_id: str
    name: str
    items: dict[str, list[PlantItem]] = field(default_factory=dict)


def plant_robots(session: Session, *, robot_id: str | None = None) -> list[PlantRobot]:
    """Every live robot with its live subjects (or only the one robot: an empty list when it
    is archived or unknown)."""
    stmt = select(Robot.id, Robot.name).where(Robot.archived_at.is_(None))
    if robot_id is not None:
        stmt = stmt.where(Robot.id == robot_id)
    robots = {r.id: PlantRobot(robot_id=r.id, name=r.name) for r in session.execute(stmt)}
    for served in IN_FLEET:
        kind = served.subject.kind
        for robot in robots.values():
            robot.items[kind] = []
        for item in plant_items(session, served, robot_id=robot_id):
            if item.robot_id in robots:
                robots[item.robot_id].items[kind].append(item)
    return list(robots.values())


def plant_items(
    session: Session, served: Served, *, robot_id: str | None = None
) -> list[PlantItem]:
    """Every live subject of its kind in the fleet (or of one live robot: none when it is
    archived or unknown), oldest first."""
    subject = served.subject
    rows = list(all_rows(session, served, robot_id=robot_id))
    items: list[PlantItem] = []
    for start in range(0, len(rows), _BATCH):
        page = rows[start : start + _BATCH]
        ids = [row.id for row in page]
        active = _active_values(session, subject, ids)
        statuses = active_statuses(session, subject, ids)
        last = last_activations(session, subject, ids)
        items.extend(
            _plant_item(row, *active[row.id], statuses.get(row.id), last.get(row.id))
            for row in page
            if row.id in active
        )
    return items


#: Subjects whose values are read per query (the ids of one IN list).
_BATCH = 500

_ActiveRow = tuple[datetime, list[float] | None, list[float] | None]


def _active_values(session: Session, subject: AnySubject, ids: list[str]) -> dict[str, _ActiveRow]:
    table, versions = subject.table, subject.versions
    stmt = (
        select(table.c.id, table.c.updated_at, versions.c.position_mm, versions.c.quaternion)
        .outerjoin(
            versions,
            and_(
                subject.version_key() == table.c.id,
                versions.c.version == table.c.active_version,
            ),
        )
        .where(table.c.id.in_(ids))
    )
    return {
        r.id: (r.updated_at, _floats(r.position_mm), _floats(r.quaternion))
        for r in session.execute(stmt)
    }


def _floats(values: object) -> list[float] | None:
    return None if not isinstance(values, list) else [float(v) for v in values]


def _plant_item(
    row: FleetRow,
    updated_at: datetime,
    position: list[float] | None,
    quaternion: list[float] | None,
    status: str | None,
    activation: LastActivation | None,
) -> PlantItem:
    value = None
    if row.active_version is not None and position is not None and quaternion is not None:
        abc = kuka_abc_from_matrix(matrix_from_quaternion_wxyz(quaternion))
        value = (tuple(position), tuple(quaternion), tuple(float(v) for v in abc))
    return PlantItem(
        subject_id=row.id,
        robot_id=row.robot_id,
        robot_name=row.robot_name,
        name=row.name,
        active_version=None if value is None else row.active_version,
        position_mm=None if value is None else value[0],
        quaternion=None if value is None else value[1],
        kuka_abc=None if value is None else value[2],
        controller_state=controller_state(row),
        updated_at=updated_at,
        status=None if value is None else status,
        activation=None if value is None else activation,
    )
