"""Activating a stored version of any subject on purpose, and rolling back along the
activation history (the subject's declaration: app.services.lifecycle.subject).

An activation a person asks for is guarded: a version stored as `out_of_tolerance` goes live
only with `force` and a reason. A rollback never picks a version by number: it returns to the
version that was active before the current one, read from the activation history.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final, Protocol

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import InvalidInput, NothingToRollBack, OutOfTolerance
from app.jsontypes import JsonObject
from app.schemas.common import Activate
from app.schemas.tools import ActivationRequest, RollbackRequest
from app.security.auth import Principal
from app.services.lifecycle.subject import (
    ActivationT,
    AnySubject,
    Row,
    Subject,
    VersionRow,
    VersionT,
)
from app.services.lifecycle.versions import activate, check_if_match, get_live, get_version, lock
from app.words import ActivationKind, Status

OUT_OF_TOLERANCE: Final[Status] = "out_of_tolerance"
#: Kinds of activation (activations.reason, app.words.ActivationKind) written here.
EXPLICIT: Final[ActivationKind] = "explicit"
FORCED: Final[ActivationKind] = "forced"
ROLLBACK: Final[ActivationKind] = "rollback"
#: The kind of a version a re-check corrected the subject to (app.services.checks.recheck).
CHECK_CORRECTION: Final[ActivationKind] = "check_correction"


class ChangeLimit(Protocol):
    """What deciding an auto-activation reads of a subject's tolerance (a tool's, a frame's)."""

    @property
    def max_change_mm(self) -> float: ...


def held_for_change(change_mm: float | None, tolerance: ChangeLimit) -> bool:
    """Whether a new version moved the subject too far from the active one (more than the
    tolerance's max_change_mm) to activate it by "auto"."""
    return change_mm is not None and change_mm > tolerance.max_change_mm


def activation_due(
    activate: Activate, status: Status, change_mm: float | None, tolerance: ChangeLimit
) -> ActivationKind | None:
    """The kind of activation a calibration's new version gets as its request's `activate`
    asks (None: it is stored, not activated): "always" always; "auto" only when it is
    accepted and within max_change_mm of the active version; "never" never."""
    if activate == "always":
        return "calibration:always"
    if activate == "auto" and status == "accepted" and not held_for_change(change_mm, tolerance):
        return "calibration:auto"
    return None


def activate_version(
    session: Session,
    subject: Subject[Row, VersionT, ActivationT],
    *,
    subject_id: str,
    version: int,
    body: ActivationRequest,
    if_match: str | None,
    actor: Principal,
) -> Row:
    """Make a stored version the active one, honouring If-Match. A version stored as
    out_of_tolerance needs `force` and a reason (409 /out-of-tolerance otherwise, nothing
    changed); `force` without a reason is a 422 on body.reason."""
    if body.force and body.reason is None:
        raise InvalidInput(
            "reason-required",
            'force needs a reason: say why this version must go live, e.g. {"force": true, '
            f'"reason": "probe bent, interim {subject.value} until the new one is calibrated"}}',
            loc=("body", "reason"),
        )
    locked = lock(session, subject, subject_id)
    check_if_match(subject, locked, if_match)
    row = get_version(session, subject, subject_id=subject_id, version=version)
    if row.status == OUT_OF_TOLERANCE and not body.force:
        raise _out_of_tolerance(session, subject, row, name=locked.name)
    activate(
        session,
        subject,
        locked=locked,
        version=version,
        reason=FORCED if row.status == OUT_OF_TOLERANCE else EXPLICIT,
        reason_text=body.reason,
        actor=actor,
        details={"status": row.status, "force": body.force},
    )
    return get_live(session, subject, subject_id)


def _out_of_tolerance(
    session: Session, subject: AnySubject, row: VersionRow, *, name: str
) -> OutOfTolerance:
    """Why the version may not go live as it is (its status and worst figure), and how."""
    figures: JsonObject = {"version": row.version, "version_status": row.status}
    worst = ""
    if row.calibration_id is not None:
        result = session.scalars(
            select(subject.calibrations.c.result).where(
                subject.calibrations.c.id == row.calibration_id
            )
        ).one()
        quality = result.get("quality")
        if isinstance(quality, dict):
            figures["rms_mm"] = quality.get("rms_mm")
            figures["max_mm"] = quality.get("max_mm")
        if isinstance(result.get("summary"), str):
            figures["summary"] = result["summary"]
            worst = f" ({result['summary']})"
        elif isinstance(figures.get("max_mm"), float):
            worst = f" (its worst touch is {figures['max_mm']:.2f} mm off)"
    return OutOfTolerance(
        f"version {row.version} of {subject.kind} {name} is stored as out_of_tolerance{worst}; "
        "nothing was changed. To put it live anyway, resend with "
        '{"force": true, "reason": "<why>"}; or calibrate again',
        members=figures,
    )


def rollback(
    session: Session,
    subject: Subject[Row, VersionT, ActivationT],
    *,
    subject_id: str,
    body: RollbackRequest,
    if_match: str | None,
    actor: Principal,
) -> Row:
    """Return to the version that was active before the current one (If-Match honoured).

    The rule, replayed from the subject's activation history (`rollback_stack`): the versions
    that have been active form a stack, most recently active on top, each version once; an
    activation (calibration, explicit, forced) moves its version to the top; a rollback
    takes the top off and activates the one below. So rolling back twice walks back through
    the history (v4 -> v3 -> v2) instead of returning to the version just left, a version
    that was never active is never chosen, and when nothing is left below the top the
    answer is 409 /nothing-to-roll-back with nothing changed. A version reached by a
    rollback is one that was live before, so it goes live whatever its status (a version
    forced live earlier comes back without `force`).
    """
    locked = lock(session, subject, subject_id)
    check_if_match(subject, locked, if_match)
    activations = subject.activations
    history = session.execute(
        select(activations.c.version, activations.c.reason)
        .where(subject.activation_key() == subject_id)
        .order_by(activations.c.id)
    )
    stack = rollback_stack((version, kind) for version, kind in history)
    if locked.active_version is None or len(stack) < 2:
        raise NothingToRollBack(
            f"{subject.kind} {locked.name} has nothing to roll back to: "
            + _why_nothing(locked.active_version)
            + "; nothing was changed. To put another stored version live, activate it: "
            f"POST {subject.path}/{subject_id}/versions/{{version}}/activate",
            members={"active_version": locked.active_version},
        )
    target = stack[-2]
    row = get_version(session, subject, subject_id=subject_id, version=target)
    activate(
        session,
        subject,
        locked=locked,
        version=target,
        reason=ROLLBACK,
        reason_text=body.reason,
        actor=actor,
        action="version.rollback",
        details={"status": row.status},
    )
    return get_live(session, subject, subject_id)


def _why_nothing(active: int | None) -> str:
    if active is None:
        return "no version has been active yet"
    return (
        f"no version was active before version {active}, or earlier rollbacks have already "
        "gone back through each one"
    )


def rollback_stack(history: Iterable[tuple[int, str]]) -> list[int]:
    """The versions a rollback can return to, the active one last, from the activation
    history (version, kind) oldest first: each activation moves its version to the top, each
    rollback removes the version it left (then its own version is the top)."""
    stack: list[int] = []
    for version, kind in history:
        if kind == ROLLBACK and stack:
            stack.pop()
        if version in stack:
            stack.remove(version)
        stack.append(version)
    return stack
