"""The transactional outbox: a row per change the plant must see, in the change's own
transaction, in commit order; nothing for a change that rolled back or for API keys."""

from __future__ import annotations

import itertools
import threading
from typing import Any

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.schemas.tools import ActivationRequest
from app.security.auth import Principal
from app.services.audit import outbox
from app.services.audit import writes as audit
from app.services.tools import activation
from app.storage.db import make_engine, session_scope
from app.storage.models import Activation, OutboxMessage, utcnow
from app.words import AuditAction
from tests.conftest import Api, Database

ACTOR = Principal(key_id="k", name="tester", scope="admin")

NO_BODY = ActivationRequest()  # an activation without a reason


def _rows() -> list[OutboxMessage]:
    with session_scope(write=False) as session:
        return list(session.scalars(select(OutboxMessage).order_by(OutboxMessage.id)))


def _setup(api: Api) -> tuple[dict[str, Any], dict[str, Any]]:
    robot = api.robot("r-outbox")
    tool = api.tool(robot["id"], "torch", slot=1)
    return robot, tool


def test_each_change_writes_one_row_with_the_event(api: Api) -> None:
    robot, tool = _setup(api)
    api.manual(tool["id"], [1.0, 2.0, 300.0])
    api.manual(tool["id"], [1.0, 2.0, 301.0])
    activated = api.post(
        f"/v1/tools/{tool['id']}/versions/1/activate",
        scope="calibrate",
        headers={"X-Request-ID": "req-activate-1"},
    )
    assert activated.status_code == 200, activated.text
    assert api.delete(f"/v1/tools/{tool['id']}").status_code == 204
    rows = _rows()
    actions = [r.action for r in rows]
    assert actions[:2] == ["robot.create", "tool.create"]
    assert actions[-1] == "tool.archive"
    assert "version.activate" in actions
    assert "calibration.create" in actions
    ids = [r.id for r in rows]
    assert ids == sorted(ids)
    assert len(set(ids)) == len(ids)
    activation = [r for r in rows if r.action == "version.activate"][-1]
    assert activation.tool_id == tool["id"]
    assert activation.robot_id == robot["id"]
    assert set(activation.payload) == {
        "action", "tool_id", "frame_id", "robot_id", "version", "actor", "at", "request_id",
        "kind", "reason",
    }  # fmt: skip
    assert activation.payload["frame_id"] is None  # every subject's key, a tool's event
    assert activation.payload["version"] == 1
    assert (activation.payload["kind"], activation.payload["reason"]) == ("explicit", None)
    archive = [r for r in rows if r.action == "tool.archive"][-1]
    assert (archive.payload["kind"], archive.payload["reason"]) == (None, None)
    assert activation.payload["request_id"] == "req-activate-1"
    assert activation.payload["actor"] == "test-calibrate"
    assert all(r.delivered_at is None for r in rows)


def test_api_keys_and_reads_write_nothing(api: Api) -> None:
    before = len(_rows())
    made = api.post("/v1/keys", {"name": "ops", "scope": "read"})
    assert made.status_code == 201, made.text
    assert api.get("/v1/tools").status_code == 200
    assert len(_rows()) == before


def _activate_then_fail(tool_id: str) -> None:
    with session_scope(write=True) as session:
        activation.activate_version(
            session, tool_id=tool_id, version=1, body=NO_BODY, if_match=None, actor=ACTOR
        )
        raise RuntimeError("the request failed after the activation")


def test_a_rolled_back_change_leaves_no_row(api: Api) -> None:
    _, tool = _setup(api)
    api.manual(tool["id"], [0.0, 0.0, 100.0])
    before = len(_rows())
    with pytest.raises(RuntimeError, match="after the activation"):
        _activate_then_fail(tool["id"])
    assert len(_rows()) == before
    with session_scope(write=True) as session:
        activation.activate_version(
            session, tool_id=tool["id"], version=1, body=NO_BODY, if_match=None, actor=ACTOR
        )
    assert [r.action for r in _rows()[before:]] == ["version.activate"]


def test_oldest_undelivered_age(api: Api) -> None:
    with session_scope(write=False) as session:
        assert outbox.oldest_undelivered_age(session) == 0.0
    _setup(api)
    with session_scope(write=False) as session:
        age = outbox.oldest_undelivered_age(session)
        assert 0.0 <= age < 60.0
        assert outbox.undelivered_count(session) >= 2


def _audit_row(tool_id: str, action: AuditAction) -> dict[str, object]:
    return audit.row(
        at=utcnow(),
        actor="tester",
        api_key_id=None,
        action=action,
        resource_type="tool",
        resource_id=tool_id,
        robot_id=None,
        tool_id=tool_id,
        details=None,
    )


def test_postgresql_allocates_outbox_ids_in_commit_order(db: Database) -> None:
    """A transaction that wrote its outbox row holds the ordering lock until it commits: a
    second one (even about the same tool without its row lock, like a check) waits, so its
    id is larger and it commits after."""
    if db.backend != "postgresql":
        pytest.skip("SQLite has one writer at a time: ids are in commit order already")
    engine = make_engine(db.url)
    first = Session(engine)
    outbox.write(first, [_audit_row("tool-a", "tool.check")])
    second_done = threading.Event()

    def second() -> None:
        with Session(engine) as session:
            outbox.write(session, [_audit_row("tool-a", "version.activate")])
            session.commit()
        second_done.set()

    thread = threading.Thread(target=second)
    thread.start()
    try:
        assert not second_done.wait(0.7), "the second transaction did not wait for the first"
        first.commit()
        assert second_done.wait(10)
    finally:
        first.close()
        thread.join(10)
        engine.dispose()
    with session_scope(write=False) as session:
        rows = list(session.scalars(select(OutboxMessage).order_by(OutboxMessage.id)))
    assert [r.action for r in rows] == ["tool.check", "version.activate"]


def test_concurrent_activations_reach_the_outbox_in_their_commit_order(api: Api) -> None:
    """Eight threads activating versions of one tool: the outbox's versions, in id order,
    are the activation history's chain (each activation's previous version is the one
    before it in the outbox)."""
    _, tool = _setup(api)
    for z in (100.0, 101.0, 102.0):
        api.manual(tool["id"], [0.0, 0.0, z], activate="never")

    def activate_some(seed: int) -> None:
        for i in range(4):
            with session_scope(write=True) as session:
                activation.activate_version(
                    session,
                    tool_id=tool["id"],
                    version=1 + (seed + i) % 3,
                    body=NO_BODY,
                    if_match=None,
                    actor=ACTOR,
                )

    threads = [threading.Thread(target=activate_some, args=(s,)) for s in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    rows = [r for r in _rows() if r.action == "version.activate"]
    assert len(rows) == 32
    with session_scope(write=False) as session:
        history = list(
            session.scalars(
                select(Activation).where(Activation.tool_id == tool["id"]).order_by(Activation.id)
            )
        )
    assert [r.payload["version"] for r in rows] == [h.version for h in history]
    for before, after in itertools.pairwise(history):
        assert after.previous_version == before.version
