"""An audit event names the calibrated subject it concerns by the subject's key (`about`), and
the outbox row written with it carries the same: the one way a second subject's events reach
the audit trail and the plant without a parameter of its own."""

from __future__ import annotations

from sqlalchemy import select

from app.security.auth import Principal
from app.services.audit import writes as audit
from app.storage.db import session_scope
from app.storage.models import AuditEvent, OutboxMessage, Robot, new_id
from tests.conftest import Api


def test_a_created_rows_event_names_its_subject_by_key(api: Api) -> None:
    del api  # the database of the test session
    actor = Principal(key_id="test", name="bob", scope="admin")
    subject_id = new_id()
    with session_scope(write=True) as session:
        robot = Robot(id=new_id(), name="r-about")
        audit.add_created(
            session,
            robot,
            actor=actor,
            action="robot.create",
            resource_type="robot",
            about={"tool_id": subject_id},
        )
    with session_scope(write=False) as session:
        event = session.execute(
            select(AuditEvent.resource_id, AuditEvent.tool_id).where(
                AuditEvent.resource_id == robot.id
            )
        ).one()
        outbox = session.execute(
            select(OutboxMessage.tool_id, OutboxMessage.payload).where(
                OutboxMessage.tool_id == subject_id
            )
        ).one()
    assert tuple(event) == (robot.id, subject_id)
    assert outbox.payload["tool_id"] == subject_id
