"""What the plant is shown of each live tool (the OPC UA address space's values): its robot
and name, the active version's TCP (also as kuka_abc), its status and how it went live
(the activation's kind and reason), the controller's state, and when the tool last changed.

Read through the fleet service (names, active version, controller state: one judge of
those), one query for the active versions' TCPs, statuses and the tools' change times, and
one for the latest activations (`activations_of`, which the MQTT sink's retained message
reads too).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime

from sqlalchemy import and_, select
from sqlalchemy.orm import Session

from app.kinematics.poses import kuka_abc_from_matrix, matrix_from_quaternion_wxyz
from app.schemas.fleet import FleetTool
from app.services.fleet.fleet import list_fleet
from app.services.fleet.gauges import PAGE, controller_state
from app.services.lifecycle.published import LastActivation, last_activations
from app.services.lifecycle.published import active_statuses as lifecycle_statuses
from app.services.tools.subject import TOOL
from app.storage.models import Robot, TcpVersion, Tool

__all__ = [
    "LastActivation",
    "PlantRobot",
    "PlantTool",
    "activations_of",
    "active_statuses",
    "plant_robots",
    "plant_tools",
]

Vector = tuple[float, ...]


@dataclass(frozen=True)
class PlantTool:
    """One live tool as the plant sees it; the TCP fields are None with no active version,
    `status` (the active version's: accepted or out_of_tolerance) and `activation` too."""

    tool_id: str
    robot_id: str
    robot_name: str
    tool_name: str
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
    """One live robot and its live tools."""

    robot_id: str
    name: str
    tools: list[PlantTool] = field(default_factory=list)


def plant_robots(session: Session, *, robot_id: str | None = None) -> list[PlantRobot]:
    """Every live robot with its live tools (or only the one robot: an empty list when it is
    archived or unknown)."""
    stmt = select(Robot.id, Robot.name).where(Robot.archived_at.is_(None))
    if robot_id is not None:
        stmt = stmt.where(Robot.id == robot_id)
    robots = {r.id: PlantRobot(robot_id=r.id, name=r.name) for r in session.execute(stmt)}
    for tool in plant_tools(session, robot_id=robot_id):
        if tool.robot_id in robots:
            robots[tool.robot_id].tools.append(tool)
    return list(robots.values())


def plant_tools(session: Session, *, robot_id: str | None = None) -> list[PlantTool]:
    """Every live tool of the fleet (or of one live robot: none when it is archived or
    unknown), oldest first."""
    tools: list[PlantTool] = []
    for page in _pages(session, robot_id):
        ids = [row.id for row in page]
        active = _active_tcps(session, ids)
        statuses = active_statuses(session, ids)
        last = activations_of(session, ids)
        tools.extend(
            _plant_tool(row, *active[row.id], statuses.get(row.id), last.get(row.id))
            for row in page
            if row.id in active
        )
    return tools


def activations_of(session: Session, tool_ids: list[str]) -> dict[str, LastActivation]:
    """Each tool's latest activation, for the tools that have one (app.services.lifecycle)."""
    return last_activations(session, TOOL, tool_ids)


def _pages(session: Session, robot_id: str | None) -> Iterator[list[FleetTool]]:
    cursor: str | None = None
    while True:
        rows, cursor = list_fleet(
            session, cell=None, robot_id=robot_id, q=None, status=None, limit=PAGE, cursor=cursor
        )
        yield rows
        if cursor is None:
            return


def active_statuses(session: Session, tool_ids: list[str]) -> dict[str, str]:
    """The status of each tool's active version, for the tools that have one."""
    return lifecycle_statuses(session, TOOL, tool_ids)


_ActiveRow = tuple[datetime, list[float] | None, list[float] | None]


def _active_tcps(session: Session, ids: list[str]) -> dict[str, _ActiveRow]:
    stmt = (
        select(Tool.id, Tool.updated_at, TcpVersion.position_mm, TcpVersion.quaternion)
        .outerjoin(
            TcpVersion,
            and_(TcpVersion.tool_id == Tool.id, TcpVersion.version == Tool.active_version),
        )
        .where(Tool.id.in_(ids))
    )
    return {
        r.id: (r.updated_at, _floats(r.position_mm), _floats(r.quaternion))
        for r in session.execute(stmt)
    }


def _floats(values: object) -> list[float] | None:
    return None if not isinstance(values, list) else [float(v) for v in values]


def _plant_tool(
    row: FleetTool,
    updated_at: datetime,
    position: list[float] | None,
    quaternion: list[float] | None,
    status: str | None,
    activation: LastActivation | None,
) -> PlantTool:
    tcp = None
    if row.active_version is not None and position is not None and quaternion is not None:
        abc = kuka_abc_from_matrix(matrix_from_quaternion_wxyz(quaternion))
        tcp = (tuple(position), tuple(quaternion), tuple(float(v) for v in abc))
    return PlantTool(
        tool_id=row.id,
        robot_id=row.robot_id,
        robot_name=row.robot_name,
        tool_name=row.name,
        active_version=None if tcp is None else row.active_version,
        position_mm=None if tcp is None else tcp[0],
        quaternion=None if tcp is None else tcp[1],
        kuka_abc=None if tcp is None else tcp[2],
        controller_state=controller_state(row),
        updated_at=updated_at,
        status=None if tcp is None else status,
        activation=None if tcp is None else activation,
    )
