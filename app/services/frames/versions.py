"""A frame's versions as the API shows them, and its active frame served (GET
/v1/frames/{frame_id}/frame): the lifecycle's hot read (app.services.lifecycle.hot_read) with
the frame's declaration, its strong ETag and 304."""

from __future__ import annotations

from typing import NamedTuple, Protocol

from sqlalchemy.orm import Session

from app.helpers.etags import if_none_match_hit
from app.schemas.frames import ActiveRobotFrame, FramePose
from app.schemas.frames import FrameVersion as FrameVersionOut
from app.security.auth import Principal
from app.services.frames.frames import get_frame
from app.services.frames.subject import FRAME
from app.services.lifecycle import hot_read
from app.services.lifecycle import versions as lifecycle
from app.services.lifecycle.hot_read import HotVersion, served_etag
from app.services.lifecycle.subject import Owned, Valued
from app.storage.db import loop_engine
from app.storage.models import Frame, FrameVersion


class ServedFrame(Owned, Protocol):
    """What serving a frame reads of it: a models.Frame, or a hot read's columns."""

    @property
    def slot(self) -> int | None: ...


class _HotFrame(NamedTuple):
    id: str
    robot_id: str
    name: str
    slot: int | None


def version_document(row: FrameVersion, frame: Frame) -> FrameVersionOut:
    """A frame's version as the API shows it."""
    return FrameVersionOut(
        version=row.version,
        frame=FramePose(position_mm=row.position_mm, quaternion=row.quaternion),
        source=row.source,
        status=row.status,
        calibration_id=row.calibration_id,
        note=row.note,
        created_at=row.created_at,
        created_by=row.created_by,
        active=frame.active_version == row.version,
    )


def frame_etag(frame: ServedFrame, row: Valued) -> str:
    """Strong ETag of what /frame serves: the frame's numbers, slot and name."""
    return served_etag(
        [frame.id, frame.slot, frame.name, row.version, row.position_mm, row.quaternion]
    )


def active_document(frame: ServedFrame, row: FrameVersion | HotVersion) -> ActiveRobotFrame:
    """The active frame as a cell controller reads it."""
    return ActiveRobotFrame(
        frame_id=frame.id,
        robot_id=frame.robot_id,
        frame_name=frame.name,
        slot=frame.slot,
        version=row.version,
        frame=FramePose(position_mm=row.position_mm, quaternion=row.quaternion),
        calibrated_at=row.created_at,
        method=row.source,
    )


def served_frame(
    session: Session, *, frame_id: str, if_none_match: str | None
) -> tuple[ActiveRobotFrame | None, str]:
    """(document, ETag) of a frame's active version in the caller's transaction (what the
    publisher publishes); the document None when the client's copy is current."""
    frame = get_frame(session, frame_id)
    row = lifecycle.active_version_row(session, FRAME, frame)
    etag = frame_etag(frame, row)
    if if_none_match_hit(if_none_match, etag):
        return None, etag
    return active_document(frame, row), etag


def served_frame_for_key(
    *, authorization: str | None, frame_id: str, if_none_match: str | None
) -> tuple[Principal, ActiveRobotFrame | None, str]:
    """`served_frame` for the caller behind `authorization`, in one statement on the event
    loop's held connection (app.storage.db.loop_engine): (who, the document or None when the
    client's copy is current, ETag)."""
    principal, found = hot_read.read_for_key(loop_engine(), FRAME, authorization, frame_id)
    row = hot_read.active_version_of(FRAME, found, principal, frame_id)
    # Columns of the frame's row, which exists, are never NULL.
    assert found.subject_id is not None
    assert found.robot_id is not None
    assert found.subject_name is not None
    frame = _HotFrame(found.subject_id, found.robot_id, found.subject_name, found.slot)
    etag = frame_etag(frame, row)
    if if_none_match_hit(if_none_match, etag):
        return principal, None, etag
    return principal, active_document(frame, row), etag
