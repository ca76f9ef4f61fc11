"""What the plant is shown of any subject's active version besides its values: the version's
status and how it went live (the latest activation's kind, words, time and author), read for
many subjects at once (the publisher's batch, the OPC UA address space)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict
from sqlalchemy import and_, func, select
from sqlalchemy.orm import Session

from app.schemas.common import Timestamp
from app.services.lifecycle.subject import AnySubject
from app.words import ActivationKind


class LastActivation(BaseModel):
    """How a subject's active version went live: the activation's kind (explicit, forced,
    rollback, calibration:auto, ...: the activations' `reason`), the words the person gave
    (None when none were), when and by whom. As JSON (`model_dump(mode="json")`) it is the
    MQTT retained message's `activation`."""

    model_config = ConfigDict(frozen=True)

    kind: ActivationKind
    reason: str | None
    at: Timestamp
    by: str


def last_activations(
    session: Session, subject: AnySubject, subject_ids: list[str]
) -> dict[str, LastActivation]:
    """Each subject's latest activation (the one that made its active version active: every
    activation, rollback and auto-activation writes one), for those that have one."""
    if not subject_ids:
        return {}
    activations, key = subject.activations, subject.activation_key()
    latest = (
        select(func.max(activations.c.id).label("id"))
        .where(key.in_(subject_ids))
        .group_by(key)
        .subquery()
    )
    rows = session.execute(
        select(
            key.label("subject_id"),
            activations.c.reason,
            activations.c.reason_text,
            activations.c.activated_at,
            activations.c.activated_by,
        ).join(latest, activations.c.id == latest.c.id)
    )
    return {
        r.subject_id: LastActivation(
            kind=r.reason, reason=r.reason_text, at=r.activated_at, by=r.activated_by
        )
        for r in rows
    }


def active_statuses(
    session: Session, subject: AnySubject, subject_ids: list[str]
) -> dict[str, str]:
    """The status of each subject's active version (accepted, out_of_tolerance), for those
    that have one."""
    table, versions = subject.table, subject.versions
    stmt = (
        select(table.c.id, versions.c.status)
        .join(
            versions,
            and_(
                subject.version_key() == table.c.id,
                versions.c.version == table.c.active_version,
            ),
        )
        .where(table.c.id.in_(subject_ids))
    )
    return {r.id: r.status for r in session.execute(stmt)}
