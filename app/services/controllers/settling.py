"""Settle an `unverified` deployment: the reconcile round after it records what the
controller holds (the written version, the frame it held before, or something else) on the
deployment and as an audit event `deployment.settled`.

Only a subject's newest deployment is settled, and only by a reading that began after it was
recorded: what a controller holds now says nothing about an attempt a later one followed,
and a reading taken while the attempt ran could show the frame from before its write.
"""

from __future__ import annotations

import functools
from datetime import datetime
from typing import NamedTuple

from sqlalchemy import bindparam, select
from sqlalchemy.orm import Session

from app.helpers.frame_deviation import (
    DEPLOY_TOLERANCE_DEG,
    DEPLOY_TOLERANCE_MM,
    frame_deviation,
    within,
)
from app.jsontypes import JsonObject
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.controllers.states import Observation
from app.services.lifecycle.subject import AnySubject
from app.storage.db import HeldRead
from app.words import DeploymentStatus, SettledHolds


def settle(
    session: Session, seen: Observation, *, read_from: datetime, at: datetime, actor: Principal
) -> None:
    """Settle the subject's newest deployment with what the round saw (at `at`), when it is
    `unverified`, not settled yet and was recorded before the round began reading
    (`read_from`)."""
    held = seen.controller
    if held is None:
        return  # not read this round: the next one will tell
    subject = seen.subject
    deployments = subject.deployments
    assert deployments is not None
    row = _newest(subject).one_or_none_in(session, subject_id=seen.subject_id)
    if row is None or row.status != "unverified" or row.settled is not None:
        return
    if row.created_at >= read_from:
        return
    versions = subject.versions
    written = session.execute(
        select(versions.c.position_mm, versions.c.quaternion).where(
            subject.version_key() == seen.subject_id, versions.c.version == row.version
        )
    ).one()
    holds: SettledHolds = "other"
    if _same(held, {"position_mm": written.position_mm, "quaternion": written.quaternion}):
        holds = "written"
    elif row.previous is not None and _same(held, row.previous):
        holds = "previous"
    settled = {"at": at.isoformat(), "holds": holds, "frame": held}
    session.execute(deployments.update().where(deployments.c.id == row.id).values(settled=settled))
    audit.record(
        session,
        actor=actor,
        action="deployment.settled",
        resource_type="deployment",
        resource_id=str(row.id),
        robot_id=row.robot_id,
        version=row.version,
        about={subject.key: seen.subject_id},
        details={
            "deployment_id": str(row.id),
            "holds": holds,
            "version": row.version,
            "target": row.target,
            "controller": held,
            "previous": row.previous,
        },
    )


class _Newest(NamedTuple):
    """What settling reads of a subject's newest deployment."""

    id: int
    robot_id: str
    version: int
    target: str
    status: DeploymentStatus
    previous: JsonObject | None
    settled: JsonObject | None
    created_at: datetime


@functools.cache
def _newest(subject: AnySubject) -> HeldRead[_Newest]:
    """The subject's newest deployment (built once a kind: a round runs it for every subject
    read, on the driver's cursor), the subject a bound parameter."""
    deployments = subject.deployments
    assert deployments is not None
    key = deployments.c[subject.key]
    return HeldRead(
        _Newest,
        select(*(deployments.c[name] for name in _Newest._fields))
        .where(key == bindparam("subject_id"))
        .order_by(deployments.c.id.desc())
        .limit(1),
    )


def _same(a: JsonObject, b: JsonObject) -> bool:
    deviation = frame_deviation(
        a["position_mm"],
        a["quaternion"],
        b["position_mm"],
        b["quaternion"],
    )
    return within(deviation, mm=DEPLOY_TOLERANCE_MM, deg=DEPLOY_TOLERANCE_DEG)
