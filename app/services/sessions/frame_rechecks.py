"""A frame's re-check as a guided session (API.md v1.4: a frame session with `"method":
"recheck"` is how a frame check gets captured touches): the frame's stored fiducials touched
again one by one, each typed or captured (the v1.3 still check, as every session's capture),
`next_role` naming the next stored fiducial not yet touched, finished as the frame's check:
app.services.checks.frame_recheck.check_frame with the session's touches and options (the
one path POST /v1/frames/{frame_id}/checks takes, never a copy).
"""

from __future__ import annotations

from typing import Protocol

from sqlalchemy.orm import Session

from app.errors import Conflict, InvalidInput
from app.jsontypes import JsonObject
from app.schemas.frame_checks import FrameCheckCreate
from app.schemas.frame_sessions import FrameTouchAdd
from app.security.auth import Principal, transaction_for
from app.services import idempotency
from app.services.audit import writes as audit
from app.services.checks import frame_recheck
from app.services.frames import checks
from app.services.frames.subject import FRAME
from app.storage.models import Frame, GuidedSession, utcnow
from app.words import Recheck

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
    answers its check again for the same Idempotency-Key, else 409."""
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
        if row.status != "open":
            keyed = (
                None
                if idempotency_key is None
                else (idempotency_key, frame_recheck.fingerprint(frame_id, data))
            )
            first = idempotency.replay_keyed(session, actor=actor, keyed=keyed, purge=False)
            if first is None:
                raise Conflict(f"session {row.id} is already finished: its check was made")
    done = frame_recheck.check_frame(
        frame_id=frame_id, data=data, actor=actor, idempotency_key=idempotency_key
    )
    if not done.replayed:
        with transaction_for(actor, write=True) as session:
            row = get_row(session, row_id, for_update=True)
            row.status, row.updated_at = "finished", utcnow()
            audit.record(
                session,
                actor=actor,
                action="session.finish",
                resource_type="session",
                resource_id=row.id,
                robot_id=done.check.robot_id,
                tool_id=row.tool_id,
                about={FRAME.key: frame_id},
                version=done.check.version,
                details={
                    "check_id": done.check.id,
                    "verdict": done.check.verdict,
                    "touches": len(row.poses),
                    "sources": list(row.touches),
                },
            )
    return done
