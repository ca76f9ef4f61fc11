"""A frame's re-check as a guided session (API.md v1.4: a frame session with `"method":
"recheck"` is how a frame check gets captured touches): the frame's stored fiducials touched
again one by one, each typed or captured (the v1.3 still check, as every session's capture),
`next_role` naming the next stored fiducial not yet touched, finished as the frame's check:
app.services.checks.frame_recheck.check_frame with the session's touches and options (the
one path POST /v1/frames/{frame_id}/checks takes, never a copy).
"""

from __future__ import annotations

import time
from typing import Any, Protocol, cast

from sqlalchemy import CursorResult, select, update
from sqlalchemy.orm import Session

from app.errors import Conflict, InvalidInput
from app.jsontypes import JsonObject
from app.schemas.frame_checks import FrameCheck, FrameCheckCreate
from app.schemas.frame_sessions import FrameTouchAdd
from app.security.auth import Principal, transaction_for
from app.services import idempotency
from app.services.checks import frame_recheck
from app.services.controllers.deployments import DEPLOYMENT_WAIT_S
from app.services.frames import checks
from app.services.frames.subject import FRAME
from app.services.sessions import rows
from app.storage.models import AuditEvent, Frame, GuidedSession, utcnow
from app.words import AuditAction, Recheck

RECHECK: Recheck = "recheck"
#: The check's options a recheck session keeps and hands to the check.
CHECK_OPTIONS = ("correct", "deploy", "reason", "scope")
#: The fewest fiducials a check takes (FrameCheckCreate.touches).
MIN_FIDUCIALS = 3


def is_recheck(row: GuidedSession) -> bool:
    return row.method == RECHECK


def stored_names(session: Session, frame: Frame) -> list[str]:
    """The frame's stored fiducials' names (422 when it keeps none: nothing to touch again)."""
    return checks.stored_fiducials(session, frame.id).names


def touched(row: GuidedSession) -> list[str]:
    return [str(t.get("fiducial")) for t in row.touches]


def next_fiducial(session: Session, row: GuidedSession, frame: Frame) -> str | None:
    """The next stored fiducial not yet touched, in the stored order; None when all are."""
    done = set(touched(row))
    return next((n for n in stored_names(session, frame) if n not in done), None)


def check_touch(session: Session, row: GuidedSession, frame: Frame, data: FrameTouchAdd) -> None:
    """The touch names a fiducial the frame has and the session has not touched yet."""
    names = stored_names(session, frame)
    if data.fiducial is None:
        following = next_fiducial(session, row, frame)
        wanted = "" if following is None else f": next is {following!r}"
        raise InvalidInput(
            "missing-role",
            f"a recheck's touches name the stored fiducial touched, one of "
            f"{', '.join(names)}{wanted}",
            loc=("body", "fiducial"),
        )
    if data.fiducial not in names:
        raise InvalidInput(
            "unknown-reference",
            f"frame {frame.name} has no fiducial {data.fiducial!r}: it has {', '.join(names)} "
            f"(GET /v1/frames/{frame.id}/fiducials); touch one of those",
            loc=("body", "fiducial"),
        )
    before = touched(row)
    if data.fiducial in before:
        index = before.index(data.fiducial)
        raise InvalidInput(
            "repeated-role",
            f"touch {index + 1} is already fiducial {data.fiducial!r}: each fiducial is "
            f"touched once; delete it first (DELETE /v1/sessions/{row.id}/poses/{index}) to "
            "touch it again",
            loc=("body", "fiducial"),
        )


def check_body(row: GuidedSession) -> FrameCheckCreate:
    """The check POST /v1/frames/{frame_id}/checks would take for the kept touches."""
    options = {k: row.options[k] for k in CHECK_OPTIONS if row.options.get(k) is not None}
    body: JsonObject = {
        "tool_id": row.tool_id,
        "format": row.format,
        "touches": [
            {"fiducial": t["fiducial"], "pose": pose}
            for pose, t in zip(row.poses, row.touches, strict=True)
        ],
        **options,
    }
    if row.units:
        body["units"] = dict(row.units)
    return FrameCheckCreate.model_validate(body)


class GetRow(Protocol):
    def __call__(self, session: Session, session_id: str, *, for_update: bool) -> GuidedSession:
        """A session the caller may see, or 404."""
        ...


def finish_request(
    *, row_id: str, idempotency_key: str | None, actor: Principal, get_row: GetRow
) -> frame_recheck.Checked:
    """POST /v1/sessions/{id}/finish of a recheck session: the frame's check of its touches
    (its transactions and its deployment its own, none open meanwhile); a finished session
    answers its check again for the same Idempotency-Key, else 409. The session is claimed
    first (a conditional update, `_claim`): of concurrent finishes one checks, and the others
    answer 409, or with the same key the first one's check."""
    with transaction_for(actor, write=False) as session:
        row = get_row(session, row_id, for_update=False)
        assert row.frame_id is not None
        frame_id = row.frame_id
        if len(row.poses) < MIN_FIDUCIALS:
            raise InvalidInput(
                "too-few-poses",
                f"the session holds {len(row.poses)} touches and a check takes at least "
                f"{MIN_FIDUCIALS} fiducials: add them (POST /v1/sessions/{row.id}/poses) "
                "before finishing",
                loc=("path", "session_id"),
            )
        data = check_body(row)
    keyed = (
        None
        if idempotency_key is None
        else (idempotency_key, frame_recheck.fingerprint(frame_id, data))
    )
    if not _claim(row_id, actor, keyed):
        return frame_recheck.check_frame(  # the first answer for this key, replayed
            frame_id=frame_id, data=data, actor=actor, idempotency_key=idempotency_key
        )
    stored: list[FrameCheck] = []
    try:
        done = frame_recheck.check_frame(
            frame_id=frame_id,
            data=data,
            actor=actor,
            idempotency_key=idempotency_key,
            on_stored=stored.append,
        )
    except BaseException:
        if stored:  # the check was made (its deployment failed): the session stays finished
            _record_finish(row_id, actor, get_row, stored[0])
        else:  # no check was made: the session may be finished again
            _unclaim(row_id, actor)
        raise
    if not done.replayed:
        _record_finish(row_id, actor, get_row, done.check)
    return done


def _record_finish(row_id: str, actor: Principal, get_row: GetRow, check: FrameCheck) -> None:
    """The session's finish audited with the check it made (what a waiting finish looks for)."""
    with transaction_for(actor, write=True) as session:
        row = get_row(session, row_id, for_update=True)
        row.updated_at = utcnow()
        rows.event(
            session,
            row,
            FINISHED,
            actor,
            {
                "check_id": check.id,
                "verdict": check.verdict,
                "touches": len(row.poses),
                "sources": list(row.touches),
            },
            robot_id=check.robot_id,
            about={FRAME.key: check.frame_id},
            version=check.version,
        )


#: The session's audit action once its check is made (how a waiting finish knows it ended).
FINISHED: AuditAction = "session.finish"
#: How often a finish with the claimed session's key looks for the first one's answer.
_POLL_S = 0.1


def _claim(row_id: str, actor: Principal, keyed: tuple[str, str] | None) -> bool:
    """Take the open session for this finish: one conditional UPDATE (open -> finished, the
    same on SQLite and PostgreSQL: the database lets one of concurrent updates match), so
    one finish checks. False when it is not open and this key's first answer is kept (to be
    replayed); 409 when it is not open otherwise: finished by a check, or being finished by
    another request (this one without a key). A keyed finish beside one still checking
    waits for its key's answer, the check's end (409: another key's) or the session open
    again (the other check refused: claimed again)."""
    deadline = time.monotonic() + DEPLOYMENT_WAIT_S
    while True:
        with transaction_for(actor, write=True) as session:
            taken = session.execute(
                update(GuidedSession)
                .where(GuidedSession.id == row_id, GuidedSession.status == "open")
                .values(status="finished", updated_at=utcnow())
                .execution_options(synchronize_session=False)
            )
            if cast(CursorResult[Any], taken).rowcount == 1:
                return True
            if idempotency.replay_keyed(session, actor=actor, keyed=keyed, purge=False):
                return False
            ended = _finish_recorded(session, row_id)
            row = session.get(GuidedSession, row_id)
            if row is not None and row.status == "open":
                continue  # the other finish's check was refused: claim it again
        if ended:
            raise Conflict(f"session {row_id} is already finished: its check was made")
        if keyed is None or time.monotonic() > deadline:
            raise Conflict(
                f"session {row_id} is being finished by another request: one finish makes "
                f"one check; its answer is the frame's check (GET /v1/sessions/{row_id})"
            )
        time.sleep(_POLL_S)


def _finish_recorded(session: Session, row_id: str) -> bool:
    return (
        session.scalar(
            select(AuditEvent.id)
            .where(
                AuditEvent.resource_type == "session",
                AuditEvent.resource_id == row_id,
                AuditEvent.action == FINISHED,
            )
            .limit(1)
        )
        is not None
    )


def _unclaim(row_id: str, actor: Principal) -> None:
    """The claim given back when the check was refused (nothing made): open again."""
    with transaction_for(actor, write=True) as session:
        session.execute(
            update(GuidedSession)
            .where(GuidedSession.id == row_id, GuidedSession.status == "finished")
            .values(status="open", updated_at=utcnow())
            .execution_options(synchronize_session=False)
        )
