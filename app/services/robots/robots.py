"""Robots: register, list, update, archive; their kinematics validated once, at the door."""

from __future__ import annotations

from collections.abc import Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import Conflict, Forbidden, InvalidInput
from app.helpers.pagination import paginate
from app.jsontypes import JsonObject
from app.kinematics.dh import kinematics_from_spec
from app.schemas.robots import Kinematics, RobotCreate, RobotUpdate
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.robots.slots import check_vendor_change
from app.services.visible import get_live, in_scope
from app.storage.models import Frame, Robot, RobotController, Tool, new_id, utcnow
from app.vendors.connector import FrameTarget
from app.vendors.registry import (
    PRESETS,
    vendor_frame_problem,
    vendor_protocols,
    vendor_speaks,
)


def get_robot(session: Session, robot_id: str, *, for_update: bool = False) -> Robot:
    """A live robot, or 404."""
    return get_live(session, Robot, robot_id, for_update=for_update)


def _robot_name_free(session: Session, name: str, *, except_id: str | None = None) -> None:
    stmt = select(Robot.id).where(Robot.name == name, Robot.archived_at.is_(None))
    if except_id:
        stmt = stmt.where(Robot.id != except_id)
    if session.scalars(stmt).first():
        raise Conflict(
            f"a robot named {name!r} already exists",
            loc=("body", "name"),
            msg="already taken",
        )


def _cell_allowed(actor: Principal, cell: str | None) -> None:
    """403 naming body.cell when a key limited to cells puts a robot outside them."""
    if actor.sees_cell(cell):
        return
    assert actor.cells is not None
    raise Forbidden(
        f"this key is limited to the cells {', '.join(actor.cells)}: set cell to one of them "
        "(a robot in another cell needs a key of that cell)",
        loc=("body", "cell"),
        msg="outside this key's cells",
    )


def create_robot(session: Session, *, data: RobotCreate, actor: Principal) -> Robot:
    """Register a robot (name unique among live robots)."""
    _cell_allowed(actor, data.cell)
    _robot_name_free(session, data.name)
    values = data.model_dump()
    values["kinematics"] = validate_kinematics(data.kinematics)
    robot = Robot(id=new_id(), **values)
    return audit.add_created(
        session,
        robot,
        actor=actor,
        action="robot.create",
        resource_type="robot",
        robot_id=robot.id,
        details={"name": robot.name, "cell": robot.cell},
    )


def list_robots(
    session: Session, *, cell: str | None, name: str | None, limit: int, cursor: str | None
) -> tuple[Sequence[Robot], str | None]:
    """Live robots, optionally filtered by cell or exact name."""
    stmt = in_scope(session, select(Robot).where(Robot.archived_at.is_(None)), Robot.id)
    if cell is not None:
        stmt = stmt.where(Robot.cell == cell)
    if name is not None:
        stmt = stmt.where(Robot.name == name)
    return paginate(
        session, stmt, created_col=Robot.created_at, id_col=Robot.id, limit=limit, cursor=cursor
    )


def update_robot(session: Session, *, robot_id: str, data: RobotUpdate, actor: Principal) -> Robot:
    """Change the fields given in the PATCH body."""
    robot = get_robot(session, robot_id, for_update=True)
    changes = data.model_dump(exclude_unset=True)
    if changes.get("name") is None:
        changes.pop("name", None)
    if "name" in changes:
        _robot_name_free(session, changes["name"], except_id=robot.id)
    if "cell" in changes:
        _cell_allowed(actor, changes["cell"])
    if "kinematics" in changes:
        changes["kinematics"] = validate_kinematics(data.kinematics)
    if changes.get("vendor") is not None:
        live = session.execute(
            select(Tool.name, Tool.slot).where(
                Tool.robot_id == robot.id, Tool.archived_at.is_(None)
            )
        )
        check_vendor_change(changes["vendor"], ((n, s) for n, s in live), loc=("body", "vendor"))
        _frames_fit(session, robot, changes["vendor"])
    if "vendor" in changes and changes["vendor"] != robot.vendor:
        _controller_speaks(session, robot, changes["vendor"])
    details = audit.changes(robot, changes, values_of=("name", "vendor", "model", "serial", "cell"))
    for key, value in changes.items():
        setattr(robot, key, value)
    robot.updated_at = utcnow()
    audit.record(
        session,
        actor=actor,
        action="robot.update",
        resource_type="robot",
        resource_id=robot.id,
        robot_id=robot.id,
        details=details,
    )
    return robot


def _frames_fit(session: Session, robot: Robot, vendor: str) -> None:
    """422 naming body.vendor and each live frame of the robot whose number or symbol a
    controller of the new vendor's maker cannot address: the check a frame's registration
    makes (app.vendors.registry.vendor_frame_problem), so that a frame valid for the old vendor
    is not left unaddressable for the new one."""
    frames = session.execute(
        select(Frame.id, Frame.name, Frame.slot, Frame.controller_symbol)
        .where(Frame.robot_id == robot.id, Frame.archived_at.is_(None))
        .order_by(Frame.name, Frame.id)
    )
    stranded: list[str] = []
    ids: list[str] = []
    for frame_id, name, slot, symbol in frames:
        problem = vendor_frame_problem(vendor, FrameTarget(slot=slot, symbol=symbol))
        if problem is None:
            continue
        place = f"slot {slot}" if slot is not None else f"controller_symbol {symbol!r}"
        stranded.append(f"frame {name!r} ({frame_id}, {place}): {problem}")
        ids.append(frame_id)
    if stranded:
        raise InvalidInput(
            "out-of-range",
            f"robot {robot.name}'s frames would not fit a {vendor!r} controller: "
            f"{'; '.join(stranded)}. Change each one's slot or controller_symbol "
            "(PATCH /v1/frames/{frame_id}) or archive it (DELETE /v1/frames/{frame_id}), "
            "then the vendor",
            loc=("body", "vendor"),
            context={"vendor": vendor, "frames": ids},
        )


def _controller_speaks(session: Session, robot: Robot, vendor: str | None) -> None:
    """422 naming body.vendor when the robot has a controller whose protocol none of the new
    vendor's maker's controllers speak (the PUT of the controller refuses the same pair):
    every capture would then talk one maker's protocol to another's controller."""
    protocol = session.scalar(
        select(RobotController.protocol).where(RobotController.robot_id == robot.id)
    )
    if protocol is None or vendor_speaks(vendor, protocol):
        return
    fitting = vendor_protocols(vendor)
    connect = f"tcpcal connect {robot.name} --protocol {fitting[0]} --host HOST"
    if vendor_speaks(robot.vendor, fitting[0]):
        todo = f"set the controller first (PUT /v1/robots/{robot.id}/controller, or {connect})"
    else:  # its present vendor refuses the new protocol: the controller has to go first
        todo = (
            f"remove the controller first (DELETE /v1/robots/{robot.id}/controller, or "
            f"tcpcal disconnect {robot.name}), then change the vendor and connect it again "
            f"({connect})"
        )
    raise InvalidInput(
        "validation",
        f"robot {robot.name}'s controller speaks {protocol}, and a {vendor!r} robot's "
        f"controllers speak {', '.join(fitting)}: {todo}; nothing was changed",
        loc=("body", "vendor"),
        context={"protocol": protocol, "vendor": vendor, "protocols": list(fitting)},
    )


def archive_robot(session: Session, *, robot_id: str, actor: Principal) -> None:
    """Archive a robot and its tools; their history stays."""
    robot = get_robot(session, robot_id, for_update=True)
    now = utcnow()
    robot.archived_at = now
    tools = session.scalars(
        select(Tool).where(Tool.robot_id == robot.id, Tool.archived_at.is_(None))
    ).all()
    for tool in tools:
        tool.archived_at = now
        tool.revision += 1
    audit.record(
        session,
        actor=actor,
        action="robot.archive",
        resource_type="robot",
        resource_id=robot.id,
        robot_id=robot.id,
        details={"archived_tools": [t.id for t in tools]},
    )


def validate_kinematics(spec: Kinematics | None) -> JsonObject | None:
    """The kinematics to store for a robot; 422 naming the field when it is unusable."""
    if spec is None:
        return None
    as_dict = spec.model_dump()
    try:
        kinematics_from_spec(as_dict, presets=PRESETS)
    except InvalidInput as exc:
        loc = ("body", "kinematics", *[p for p in exc.loc if p != "kinematics"])
        raise InvalidInput("invalid-kinematics", exc.detail, loc=loc) from exc
    return as_dict
