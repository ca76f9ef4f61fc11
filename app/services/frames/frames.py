"""Frames of a robot: register, list, update, archive (contract v1.4 "Frames"). A frame's
number or symbol is checked against the protocols of the robot's maker (the one check a
deployment makes, app.vendors.maker.WireProtocol.frame_problem), as a tool's slot is; its
ETag and If-Match are the lifecycle's."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import InvalidInput
from app.helpers.pagination import paginate
from app.schemas.frame_tolerance import FrameTolerance
from app.schemas.frames import FrameCreate, FrameUpdate
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.frames.subject import FRAME
from app.services.lifecycle.versions import (
    Patch,
    Taken,
    apply_update,
    check_if_match,
    check_unique,
    get_live,
    patched,
)
from app.services.robots.robots import get_robot
from app.storage.models import Frame, Robot, new_id, utcnow
from app.vendors.connector import FrameTarget
from app.vendors.registry import vendor_frame_problem


def get_frame(session: Session, frame_id: str) -> Frame:
    """A live frame of a robot the caller's key may see, or 404 (/not-found, /archived)."""
    return get_live(session, FRAME, frame_id)


def frame_tolerance(stored: Mapping[str, object] | None) -> FrameTolerance:
    """A frame's tolerance with the defaults filled in."""
    return FrameTolerance.model_validate(stored or {})


def _lock_frame(session: Session, frame_id: str) -> Frame:
    """A live frame, its row locked for the rest of the transaction, or 404."""
    get_frame(session, frame_id)  # the 404 as any read says it (cells, archived)
    return session.scalars(select(Frame).where(Frame.id == frame_id).with_for_update()).one()


def check_place(robot: Robot, *, slot: int | None, symbol: str | None) -> None:
    """422 at body.slot or body.controller_symbol when the robot's maker cannot name a frame
    by it (a number outside its frame numbers, a symbol not of its form); a maker naming
    frames by their values, or a vendor no maker is known by, keeps either."""
    for field, target in (
        ("slot", FrameTarget(slot=slot)),
        ("controller_symbol", FrameTarget(symbol=symbol)),
    ):
        problem = vendor_frame_problem(robot.vendor, target)
        if problem is not None:
            raise InvalidInput("out-of-range", problem, loc=("body", field))


#: A taken name or slot, in the frame's words (check_unique).
_TAKEN = Taken(
    name="robot {robot_id} already has a frame named {name!r}; name this one otherwise, "
    "or archive the other first (DELETE /v1/frames/{other})",
    slot="slot {slot} of robot {robot_id} is already taken by another of its frames; "
    "give another slot, or archive that frame first",
)


def create_frame(session: Session, *, robot_id: str, data: FrameCreate, actor: Principal) -> Frame:
    """Register a frame on a robot (name and slot unique among the robot's live frames)."""
    robot = get_robot(session, robot_id, for_update=True)
    check_place(robot, slot=data.slot, symbol=data.controller_symbol)
    check_unique(session, FRAME, _TAKEN, robot_id, {"name": data.name, "slot": data.slot})
    frame = Frame(id=new_id(), robot_id=robot_id, last_version=0, revision=1, **data.model_dump())
    return audit.add_created(
        session,
        frame,
        actor=actor,
        action="frame.create",
        resource_type=FRAME.kind,
        robot_id=robot_id,
        about={FRAME.key: frame.id},
        details={
            "name": frame.name,
            "kind": frame.kind,
            "slot": frame.slot,
            "controller_symbol": frame.controller_symbol,
            "tolerance": frame.tolerance,
        },
    )


def list_frames(
    session: Session, *, robot_id: str, limit: int, cursor: str | None
) -> tuple[Sequence[Frame], str | None]:
    """Live frames of a robot, oldest first."""
    get_robot(session, robot_id)  # 404 for a robot of another cell: its frames are not listed
    stmt = select(Frame).where(Frame.robot_id == robot_id, Frame.archived_at.is_(None))
    return paginate(
        session, stmt, created_col=Frame.created_at, id_col=Frame.id, limit=limit, cursor=cursor
    )


#: What a frame's PATCH writes: its event shows the old and new values of all its fields
#: but the free text.
_PATCH = Patch(
    action="frame.update",
    shown=("name", "slot", "controller_symbol", "tolerance"),
    tolerance=frame_tolerance,
)


def update_frame(
    session: Session, *, frame_id: str, data: FrameUpdate, if_match: str | None, actor: Principal
) -> Frame:
    """Change the fields given in the PATCH body (If-Match honoured; the tolerance merges with
    what is stored)."""
    frame = _lock_frame(session, frame_id)
    check_if_match(FRAME, frame, if_match)
    changes = patched(data)
    robot = get_robot(session, frame.robot_id)
    check_place(robot, slot=changes.get("slot"), symbol=changes.get("controller_symbol"))
    check_unique(session, FRAME, _TAKEN, frame.robot_id, changes, except_id=frame.id)
    apply_update(session, FRAME, _PATCH, frame, changes, actor=actor)
    return frame


def archive_frame(session: Session, *, frame_id: str, actor: Principal) -> None:
    """Archive a frame: it stops serving its active pose; its history stays."""
    frame = _lock_frame(session, frame_id)
    frame.archived_at = utcnow()
    frame.revision += 1
    audit.record(
        session,
        actor=actor,
        action="frame.archive",
        resource_type=FRAME.kind,
        resource_id=frame.id,
        robot_id=frame.robot_id,
        about={FRAME.key: frame.id},
    )
