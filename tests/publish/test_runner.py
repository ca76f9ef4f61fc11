"""The runner's contract with a sink, in process: the full state per connection, batches in
id order with the tools' current states, nothing marked delivered that a sink refused."""

from __future__ import annotations

import threading

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.publish import source
from app.publish.runner import DELIVERED, FAILED, IDLE, Runner
from app.publish.sink import Batch
from app.services.lifecycle import published
from app.services.lifecycle.subject import AnySubject
from app.storage.db import get_engine, session_scope
from app.storage.models import OutboxMessage
from tests.conftest import Api
from tests.publish.plant_changes import force, out_of_tolerance_version


class RecordingSink:
    """Accepts (or, with `refuse`, refuses) what it is given, and keeps it."""

    name = "recording"

    def __init__(self) -> None:
        self.connection = 1
        self.refuse = False
        self.batches: list[Batch] = []

    def open(self, stopping: threading.Event) -> None:
        del stopping

    def connection_id(self) -> int:
        return self.connection

    def deliver(self, batch: Batch) -> bool:
        self.batches.append(batch)
        return not self.refuse

    def close(self) -> None:
        pass


def _undelivered() -> list[str]:
    with session_scope(write=False) as session:
        return list(
            session.scalars(
                select(OutboxMessage.action).where(OutboxMessage.delivered_at.is_(None))
            )
        )


def test_a_refused_batch_stays_undelivered_and_is_sent_again_with_fresh_states(
    api: Api,
) -> None:
    robot = api.robot("r-runner")
    tool = api.tool(robot["id"], "t")
    api.manual(tool["id"], [1.0, 2.0, 3.0])
    api.manual(tool["id"], [1.0, 2.0, 4.0], activate="never")
    sink = RecordingSink()
    runner = Runner(get_engine(), [sink], threading.Event(), keep_s=3600)

    assert runner.step() == DELIVERED
    full, first = sink.batches
    assert full.full
    assert not full.messages
    assert [s.subject_id for s in full.states] == [tool["id"]]
    assert [m.id for m in first.messages] == sorted(m.id for m in first.messages)
    assert first.messages[0].action == "robot.create"
    assert _undelivered() == []
    assert runner.step() == IDLE

    sink.refuse = True
    activated = api.post(f"/v1/tools/{tool['id']}/versions/2/activate", scope="calibrate")
    assert activated.status_code == 200
    assert runner.step() == FAILED
    assert _undelivered() == ["version.activate"]

    sink.refuse = False
    assert api.delete(f"/v1/tools/{tool['id']}").status_code == 204
    assert runner.step() == DELIVERED
    again = sink.batches[-1]
    assert [m.action for m in again.messages] == ["version.activate", "tool.archive"]
    (state,) = again.states
    assert state.archived
    assert state.document is None  # read now: archived, whatever the activation said
    assert _undelivered() == []

    sink.connection = 2  # reconnected: every live tool's state again, before the outbox
    api.tool(robot["id"], "t2")
    assert runner.step() == DELIVERED
    assert sink.batches[-2].full
    assert [s.name for s in sink.batches[-2].states] == ["t2"]
    assert [m.action for m in sink.batches[-1].messages] == ["tool.create"]


def test_delivered_rows_are_pruned_after_keep_s(api: Api) -> None:
    api.robot("r-prune")
    sink = RecordingSink()
    assert Runner(get_engine(), [sink], threading.Event(), keep_s=3600).step() == DELIVERED
    with session_scope(write=False) as session:
        assert len(list(session.scalars(select(OutboxMessage.id)))) == 1  # kept, delivered
    api.robot("r-prune-2")
    assert Runner(get_engine(), [sink], threading.Event(), keep_s=0).step() == DELIVERED
    with session_scope(write=False) as session:
        assert list(session.scalars(select(OutboxMessage.id))) == []


def test_a_published_state_is_read_as_of_one_moment(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A tool's active version and that version's status are read by separate statements: an
    activation committed between them must not publish an out-of-tolerance TCP as `accepted`
    (a fresh clone's .ci/run on PostgreSQL met it: test_mqtt.py:377)."""
    robot = api.robot("r-moment")
    tool = api.tool(robot["id"], "t")
    api.manual(tool["id"], [0.0, 0.0, 150.0])
    bad = out_of_tolerance_version(api, tool["id"])
    real = published.active_statuses
    forced: list[int] = []

    def then_activated(session: Session, subject: AnySubject, ids: list[str]) -> dict[str, str]:
        found = real(session, subject, ids)
        if not forced:  # the forced activation commits between the two reads, once
            force(api, tool["id"], bad, "activated between two reads of the publisher")
            forced.append(bad)
        return found

    monkeypatch.setattr(source, "active_statuses", then_activated)
    sink = RecordingSink()
    runner = Runner(get_engine(), [sink], threading.Event(), keep_s=3600)
    while runner.step() == DELIVERED:
        pass
    assert forced == [bad]
    shown = [
        (state.document["version"], state.document["status"])
        for batch in sink.batches
        for state in batch.states
        if state.subject_id == tool["id"] and state.document is not None
    ]
    assert shown, "the tool's state was never published"
    status_of = {1: "accepted", bad: "out_of_tolerance"}
    assert [(version, status_of[version]) for version, _ in shown] == shown
