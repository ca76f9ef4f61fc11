"""The version writes under a tool's lock (Core statements, app.services.lifecycle.versions) and the
audit trail written at commit: an ORM copy of the tool in the same session reads the writes
back, and a transaction that rolls back leaves no version and no audit event behind."""

from __future__ import annotations

import pytest
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.security.auth import Principal
from app.services.lifecycle import versions as lifecycle
from app.services.tools import versions
from app.services.tools.subject import TOOL
from app.services.tools.tools import get_tool, tool_etag
from app.storage.db import session_scope
from app.storage.models import AuditEvent, TcpVersion
from tests.conftest import Api

ACTOR = Principal(key_id="test", name="test", scope="admin")


def _add(tool: versions.LockedTool, session: Session) -> int:
    return lifecycle.add_version(
        session,
        TOOL,
        locked=tool,
        position_mm=[1.0, 2.0, 3.0],
        quaternion=[1.0, 0.0, 0.0, 0.0],
        source="manual",
        status="accepted",
        calibration_id=None,
        note=None,
        actor=ACTOR,
    )


def test_an_orm_copy_of_the_tool_reads_the_locked_writes_back(api: Api) -> None:
    tid = api.tool(api.robot("kr")["id"])["id"]
    with session_scope(write=True) as session:
        orm_tool = get_tool(session, tid)  # loaded before the lock, as guided sessions do
        etag_before, revision_before = tool_etag(orm_tool), orm_tool.revision
        locked = versions.lock_tool(session, tid)
        number = _add(locked, session)
        lifecycle.activate(
            session, TOOL, locked=locked, version=number, reason="explicit", actor=ACTOR
        )
        assert (orm_tool.active_version, orm_tool.last_version) == (number, number)
        assert orm_tool.revision == revision_before + 2
        assert tool_etag(orm_tool) != etag_before
    served = api.get(f"/v1/tools/{tid}/tcp").json()
    assert served["version"] == number
    assert served["tcp"]["position_mm"] == [1.0, 2.0, 3.0]


def test_a_rolled_back_write_leaves_no_version_and_no_audit_event(api: Api) -> None:
    tid = api.tool(api.robot("kr")["id"])["id"]

    def counts() -> tuple[int, int]:
        with session_scope(write=False) as session:
            n_versions = session.scalar(
                select(func.count()).select_from(TcpVersion).where(TcpVersion.tool_id == tid)
            )
            n_events = session.scalar(
                select(func.count()).select_from(AuditEvent).where(AuditEvent.tool_id == tid)
            )
            return int(n_versions or 0), int(n_events or 0)

    def write_then_fail() -> None:
        with session_scope(write=True) as session:
            _add(versions.lock_tool(session, tid), session)
            raise RuntimeError("the request failed after the write")

    before = counts()
    with pytest.raises(RuntimeError):
        write_then_fail()
    assert counts() == before

    with session_scope(write=True) as session:
        _add(versions.lock_tool(session, tid), session)
    n_versions, n_events = counts()
    assert (n_versions, n_events) == (before[0] + 1, before[1] + 1)
    with session_scope(write=False) as session:
        event = session.scalars(
            select(AuditEvent).where(AuditEvent.tool_id == tid).order_by(AuditEvent.id.desc())
        ).first()
    assert event is not None
    assert (event.action, event.actor, event.version, event.details) == (
        "version.create",
        "test",
        n_versions,
        {"source": "manual", "status": "accepted"},
    )


def test_driver_writes_store_what_the_orm_reads_back(api: Api) -> None:
    """The writes on the driver's cursor go through the models' types: timestamps come back
    as the same UTC instants, JSON as the same lists, on SQLite and PostgreSQL."""
    from datetime import UTC, datetime

    tid = api.tool(api.robot("kr")["id"])["id"]
    at = datetime(2026, 11, 23, 17, 4, 5, 123456, tzinfo=UTC)
    with session_scope(write=True) as session:
        locked = versions.lock_tool(session, tid)
        number = lifecycle.add_version(
            session,
            TOOL,
            locked=locked,
            position_mm=[1.25, -2.5, 3e-7],
            quaternion=[0.0, 1.0, 0.0, 0.0],
            source="manual",
            status="accepted",
            calibration_id=None,
            note="ü note",
            actor=ACTOR,
            created_at=at,
        )
    with session_scope(write=False) as session:
        row = versions.get_version(session, tool_id=tid, version=number)
        assert row.created_at == at
        assert row.position_mm == [1.25, -2.5, 3e-7]
        assert row.quaternion == [0.0, 1.0, 0.0, 0.0]
        assert row.note == "ü note"
        tool = get_tool(session, tid)
        assert (tool.last_version, tool.updated_at) == (number, at)


def test_a_driver_write_refuses_a_statement_left_without_values(api: Api) -> None:
    from sqlalchemy import bindparam, update

    from app.storage.db import DriverWrite
    from app.storage.models import Tool

    tid = api.tool(api.robot("kr")["id"])["id"]
    write = DriverWrite(
        update(Tool).where(Tool.id == bindparam("tool_id")).values(name=bindparam("name"))
    )
    with session_scope(write=True) as session, pytest.raises(ValueError, match="name"):
        write.execute(session, [{"tool_id": tid}])
