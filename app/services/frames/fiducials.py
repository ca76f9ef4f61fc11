"""A frame's fiducials (contract v1.4 "Fiducials"): the points the calibration of its active
version kept, with their coordinates in the frame, to be touched again after a move; named by
the method (a role, "p3") and renamed by PUT."""

from __future__ import annotations

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from app.errors import InvalidInput
from app.schemas.frame_results import Fiducial
from app.schemas.frames import FiducialList, FiducialNames
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.frames.frames import get_frame
from app.services.frames.subject import FRAME
from app.services.lifecycle import versions as lifecycle
from app.storage.models import Frame, FrameFiducial


def _kept_by(session: Session, frame: Frame) -> str | None:
    """The calibration of the frame's active version (None: no active version, or one
    entered without a calibration)."""
    if frame.active_version is None:
        return None
    return lifecycle.active_version_row(session, FRAME, frame).calibration_id


def _rows(session: Session, calibration_id: str | None) -> list[FrameFiducial]:
    if calibration_id is None:
        return []
    return list(
        session.scalars(
            select(FrameFiducial)
            .where(FrameFiducial.calibration_id == calibration_id)
            .order_by(FrameFiducial.seq)
        )
    )


def _listed(frame: Frame, calibration_id: str | None, rows: list[FrameFiducial]) -> FiducialList:
    return FiducialList(
        frame_id=frame.id,
        calibration_id=calibration_id,
        items=[Fiducial(name=r.name, nominal_mm=r.nominal_mm) for r in rows],
    )


def list_fiducials(session: Session, *, frame_id: str) -> FiducialList:
    """The fiducials of the frame's active version, in the order they were touched."""
    frame = get_frame(session, frame_id)
    calibration_id = _kept_by(session, frame)
    return _listed(frame, calibration_id, _rows(session, calibration_id))


def name_fiducials(
    session: Session, *, frame_id: str, data: FiducialNames, actor: Principal
) -> FiducialList:
    """Rename the active version's fiducials, one name each in their order (names unique)."""
    frame = get_frame(session, frame_id)
    calibration_id = _kept_by(session, frame)
    rows = _rows(session, calibration_id)
    if len(data.names) != len(rows):
        raise InvalidInput(
            "invalid-options",
            f"frame {frame.name} keeps {len(rows)} fiducials (GET /v1/frames/{frame_id}/"
            f"fiducials) and {len(data.names)} names were given: give one name for each, in "
            "their order",
            loc=("body", "names"),
        )
    repeated = sorted({n for n in data.names if data.names.count(n) > 1})
    if repeated:
        raise InvalidInput(
            "invalid-options",
            f"each fiducial needs a name of its own; {', '.join(map(repr, repeated))} is given "
            "more than once",
            loc=("body", "names"),
        )
    before = [r.name for r in rows]
    kept = [(r.seq, r.nominal_mm, r.point_mm) for r in rows]
    # replaced, not updated in place: a swap of two names would pass through a duplicate
    session.execute(delete(FrameFiducial).where(FrameFiducial.calibration_id == calibration_id))
    assert calibration_id is not None or not kept  # names were given for none: no rows
    renamed = [
        FrameFiducial(
            frame_id=frame.id,
            calibration_id=calibration_id,
            seq=seq,
            name=name,
            nominal_mm=nominal,
            point_mm=point,
        )
        for (seq, nominal, point), name in zip(kept, data.names, strict=True)
    ]
    session.add_all(renamed)
    audit.record(
        session,
        actor=actor,
        action="frame.fiducials",
        resource_type=FRAME.kind,
        resource_id=frame.id,
        robot_id=frame.robot_id,
        about={FRAME.key: frame.id},
        version=frame.active_version,
        details={"calibration_id": calibration_id, "from": before, "to": list(data.names)},
    )
    session.flush()
    return _listed(frame, calibration_id, renamed)
