"""A frame served in a controller's words (contract v1.4: GET /v1/frames/{frame_id}/frame with
`?format=` adds ``controller``, `Accept: text/plain` the file the controller loads) and a
robot's frame table (GET /v1/robots/{robot_id}/frame-table), as a tool's TCP and tool table
are (app.services.tools.controller_files), through the makers' frame modules
(app.vendors.<maker>.frame).

The served frame is the lifecycle's hot read (the key check, the frame and its active version
in one statement) and one more indexed read of the frame's kind, which the text needs (a fixed
tool is written as one) and the hot read does not carry.
"""

from __future__ import annotations

from typing import NamedTuple

from sqlalchemy import and_, bindparam, select
from sqlalchemy.orm import Session

from app.config import get_settings
from app.errors import InvalidInput
from app.helpers.etags import if_none_match_hit
from app.schemas.frames import ActiveRobotFrame, FrameTable
from app.security.auth import Principal
from app.services.frames.controller_text import ServedFrame, controller_text, frame_data
from app.services.frames.subject import FRAME
from app.services.frames.versions import active_document, served_frame_for_key
from app.services.lifecycle import hot_read
from app.services.lifecycle.hot_read import HotVersion, served_etag
from app.services.robots.robots import get_robot
from app.services.tools.controller_files import needs_format, public_url
from app.storage.db import HeldRead, loop_engine
from app.storage.models import Frame, FrameVersion
from app.vendors.files import ControllerFile, FileContext, Provenance
from app.vendors.frame import FileFrame
from app.vendors.registry import frame_file
from app.words import ControllerFormat


class _Kind(NamedTuple):
    kind: str


#: The frame's kind by id (the hot read carries its slot and symbol, not its kind).
_KIND_READ = HeldRead(
    _Kind, select(Frame.__table__.c.kind).where(Frame.__table__.c.id == bindparam("frame_id"))
)


class _HotFrame(NamedTuple):
    id: str
    robot_id: str
    name: str
    slot: int | None
    kind: str
    controller_symbol: str | None


class ServedFrameAnswer(NamedTuple):
    """Who asked, the answer's ETag and the answer: the JSON document (with the controller's
    text) or the controller's file, neither when the client's copy is current (304)."""

    key: Principal
    etag: str
    document: ActiveRobotFrame | None = None
    file: ControllerFile | None = None


def file_frame(
    frame: ServedFrame, version: FrameVersion | HotVersion, *, base_url: str
) -> FileFrame:
    """A frame's active version as a file holds it, with its provenance."""
    origin = Provenance(
        version=version.version,
        calibrated_at=version.created_at,
        calibrated_by=version.created_by,
        method=version.source,
        url=f"{base_url}/ui/frames/{frame.id}",
    )
    return FileFrame(frame_data(frame, version), origin)


def served_active(
    frame_id: str,
    /,
    *,
    authorization: str | None,
    fmt: ControllerFormat | None,
    if_none_match: str | None,
    file_base_url: str | None,
) -> ServedFrameAnswer:
    """GET /v1/frames/{frame_id}/frame's use case: the active frame as JSON in one statement
    (app.services.frames.versions.served_frame_for_key), or with controller `fmt`'s text, or
    as its file (`served_for_key`)."""
    if fmt is None and file_base_url is None:
        key, document, etag = served_frame_for_key(
            authorization=authorization, frame_id=frame_id, if_none_match=if_none_match
        )
        return ServedFrameAnswer(key, etag, document=document)
    return served_for_key(
        authorization=authorization,
        frame_id=frame_id,
        fmt=fmt,
        if_none_match=if_none_match,
        file_base_url=file_base_url,
    )


def served_for_key(
    *,
    authorization: str | None,
    frame_id: str,
    fmt: ControllerFormat | None,
    if_none_match: str | None,
    file_base_url: str | None,
) -> ServedFrameAnswer:
    """The active frame for the caller behind `authorization`, in controller `fmt`'s text
    (JSON), or as its file when `file_base_url` (the server's URL, which the header names) is
    given. A key limited to cells finds another cell's frame as absent as an unknown one."""
    engine = loop_engine()
    principal, found = hot_read.read_for_key(engine, FRAME, authorization, frame_id)
    row = hot_read.active_version_of(FRAME, found, principal, frame_id)
    fmt = needs_format(fmt)
    kind = _KIND_READ.one_or_none(engine, frame_id=frame_id)
    # Columns of the frame's row, which exists, are never NULL.
    assert found.subject_id is not None
    assert found.robot_id is not None
    assert found.subject_name is not None
    assert kind is not None
    frame = _HotFrame(
        found.subject_id,
        found.robot_id,
        found.subject_name,
        found.slot,
        kind.kind,
        found.controller_symbol,
    )
    url = public_url(file_base_url) if file_base_url is not None else None
    frame_part = [frame.id, frame.slot, frame.name, frame.kind, frame.controller_symbol]
    version_part = [row.version, row.position_mm, row.quaternion, row.created_by]
    etag = served_etag([*frame_part, *version_part, fmt, "file" if url else "json", url])
    if if_none_match_hit(if_none_match, etag):
        return ServedFrameAnswer(principal, etag)
    if url is not None:
        item = file_frame(frame, row, base_url=url)
        return ServedFrameAnswer(
            principal, etag, file=frame_file(fmt, [item], FileContext(server_url=url))
        )
    document = active_document(frame, row)
    document.controller = controller_text(fmt, frame=frame, version=row)
    return ServedFrameAnswer(principal, etag, document=document)


def _live_frames(session: Session, robot_id: str) -> list[tuple[Frame, FrameVersion]]:
    return [
        (frame, version)
        for frame, version in session.execute(
            select(Frame, FrameVersion)
            .join(
                FrameVersion,
                and_(
                    FRAME.version_key() == Frame.id,
                    FrameVersion.version == Frame.active_version,
                ),
            )
            .where(Frame.robot_id == robot_id, Frame.archived_at.is_(None))
            .order_by(Frame.slot, Frame.name)
        ).all()
    ]


def _uncalibrated(session: Session, robot_id: str) -> list[Frame]:
    return list(
        session.scalars(
            select(Frame)
            .where(
                Frame.robot_id == robot_id,
                Frame.archived_at.is_(None),
                Frame.active_version.is_(None),
            )
            .order_by(Frame.name)
        ).all()
    )


def frame_table(session: Session, *, robot_id: str, fmt: ControllerFormat | None) -> FrameTable:
    """Every live frame's active version; with `fmt`, each in the controller's text, a frame
    the format cannot express (no number where it numbers frames) carrying its own
    controller_error instead of failing the whole table."""
    get_robot(session, robot_id)
    items: list[ActiveRobotFrame] = []
    for frame, version in _live_frames(session, robot_id):
        item = active_document(frame, version)
        if fmt is not None:
            try:
                item.controller = controller_text(fmt, frame=frame, version=version)
            except InvalidInput as exc:
                item.controller_error = {
                    "type": get_settings().problem_type(exc.kind),
                    "detail": exc.detail,
                }
        items.append(item)
    missing = [frame.id for frame in _uncalibrated(session, robot_id)]
    return FrameTable(robot_id=robot_id, items=items, without_active_version=missing)


def robot_frame_file(
    session: Session, *, robot_id: str, fmt: ControllerFormat | None, base_url: str
) -> ControllerFile:
    """Every live frame of a robot with an active version, in one file of format `fmt`;
    frames the format cannot hold are named in its header."""
    fmt = needs_format(fmt)
    robot = get_robot(session, robot_id)
    url = public_url(base_url)
    items = [file_frame(f, v, base_url=url) for f, v in _live_frames(session, robot_id)]
    context = FileContext(
        robot=robot.name,
        server_url=url,
        table=True,
        without_version=tuple(f.name for f in _uncalibrated(session, robot_id)),
    )
    return frame_file(fmt, items, context)
