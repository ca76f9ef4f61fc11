"""`tcpcal publish` against a real Mosquitto, observed by a real subscriber (paho): the
retained per-tool topic, the events, the status, broker and publisher deaths, two
publishers. The tests of the outbox's order, a drain cut short and the publishers' lock run on
SQLite and, with TCPCAL_TEST_DATABASE_URL, on PostgreSQL; those of the broker protocol and the
process (@one_backend) on one of them (tests/conftest.py says which and why)."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import select

from app.storage.db import session_scope
from app.storage.models import AuditEvent, OutboxMessage
from tests.api.frame_versions import add_frame_version
from tests.conftest import Api, one_backend
from tests.polling import wait_for
from tests.publish.mqtt_harness import Broker, Publisher, Subscriber, needs_mosquitto
from tests.publish.plant_changes import force, out_of_tolerance_version, rollback

pytestmark = [needs_mosquitto, pytest.mark.live]


@pytest.fixture
def publishers(tmp_path: Path) -> Iterator[list[Publisher]]:
    started: list[Publisher] = []
    yield started
    for p in started:
        p.kill()


def _publisher(
    started: list[Publisher], tmp: Path, api: Api, broker: Broker, prefix: str, **env: str
) -> Publisher:
    database_url = os.environ["TCPCAL_DATABASE_URL"]  # the test database (the db fixture)
    p = Publisher(tmp, database_url, broker.url(), prefix, **env).start()
    started.append(p)
    return p


def _online(sub: Subscriber) -> bool:
    status = sub.on("status")
    return bool(status) and status[-1].payload == b"online"


def _tool_with_versions(api: Api, robot_id: str, name: str, n: int = 2) -> dict[str, Any]:
    tool = api.tool(robot_id, name)
    for i in range(n):
        api.manual(tool["id"], [1.0 + i, 2.0, 300.0 + i], activate="never")
    return tool


def _activate(api: Api, tool_id: str, version: int) -> float:
    response = api.post(f"/v1/tools/{tool_id}/versions/{version}/activate", scope="calibrate")
    assert response.status_code == 200, response.text
    return time.monotonic()


def _served(api: Api, tool_id: str) -> dict[str, Any] | None:
    """The retained message a tool must have, read from the API: GET /tcp's document and
    ETag, the active version's status (GET /versions) and its latest activation (the
    versions' activation history), as API.md v1.3 adds them."""
    response = api.get(f"/v1/tools/{tool_id}/tcp")
    if response.status_code != 200:
        return None
    history = api.get(f"/v1/tools/{tool_id}/versions").json()
    version = response.json()["version"]
    (status,) = [v["status"] for v in history["items"] if v["version"] == version]
    last = history["activations"][-1]
    assert last["version"] == version
    activation = {
        "kind": last["reason"],  # the API's activation `reason` is the kind
        "reason": last["reason_text"],
        "at": last["activated_at"],
        "by": last["activated_by"],
    }
    return {
        **response.json(),
        "etag": response.headers["ETag"],
        "status": status,
        "activation": activation,
    }


def _retained_now(broker: Broker, prefix: str, tool_id: str) -> bytes | None:
    """What a subscriber arriving now receives on the tool's topic (None: nothing)."""
    late = Subscriber(broker, prefix)
    try:
        time.sleep(0.3)  # retained messages arrive right after SUBACK
        got = [m for m in late.on(f"tools/{tool_id}/tcp") if m.retain]
        return got[-1].payload if got else None
    finally:
        late.close()


def _audit_order(tool_ids: set[str]) -> list[tuple[str, str, str]]:
    with session_scope(write=False) as session:
        rows = session.scalars(
            select(AuditEvent).where(AuditEvent.tool_id.in_(tool_ids)).order_by(AuditEvent.id)
        )
        return [(r.tool_id or "", r.action, r.at.isoformat().replace("+00:00", "Z")) for r in rows]


def _event_keys(sub: Subscriber, tool_ids: set[str]) -> list[tuple[str, str, str]]:
    return [(e["tool_id"], e["action"], e["at"]) for e in sub.events() if e["tool_id"] in tool_ids]


def _first_occurrences(keys: list[tuple[str, str, str]]) -> list[tuple[str, str, str]]:
    seen: dict[tuple[str, str, str], None] = {}
    for k in keys:
        seen.setdefault(k, None)
    return list(seen)


def _per_tool(keys: list[tuple[str, str, str]], tool_id: str) -> list[tuple[str, str, str]]:
    return [k for k in keys if k[0] == tool_id]


@one_backend
def test_activation_is_retained_within_a_second_and_equals_get_tcp(
    api: Api, broker: Broker, prefix: str, tmp_path: Path, publishers: list[Publisher]
) -> None:
    robot = api.robot("r-mqtt")
    tool = _tool_with_versions(api, robot["id"], "torch")
    sub = Subscriber(broker, prefix)
    _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: _online(sub), 30, "the publisher's status online")
    topic = f"tools/{tool['id']}/tcp"
    wait_for(lambda: _outbox_size() == 0, 10, "the changes made before it started sent")
    assert sub.on(topic)[-1].payload == b""  # no active version yet: cleared

    activated_at = _activate(api, tool["id"], 2)
    wait_for(lambda: sub.on(topic)[-1].payload != b"", 1.0, "the retained message within 1 s")
    message = sub.on(topic)[-1]
    assert message.at - activated_at < 1.0
    assert message.json() == _served(api, tool["id"])
    assert message.json()["version"] == 2

    late = _retained_now(broker, prefix, tool["id"])
    assert late is not None
    assert late == message.payload  # a late subscriber gets the current state

    events = [e for e in sub.events() if e["action"] == "version.activate"]
    assert len(events) == 1
    assert events[0]["tool_id"] == tool["id"]
    assert events[0]["robot_id"] == robot["id"]
    assert events[0]["version"] == 2
    assert events[0]["actor"] == "test-calibrate"
    assert set(events[0]) == {
        "action",
        "tool_id",
        "frame_id",  # every subject's key (app.storage.models.SUBJECT_KEYS): null here
        "robot_id",
        "version",
        "actor",
        "at",
        "request_id",
        "kind",
        "reason",
    }
    assert events[0]["request_id"]
    assert (events[0]["kind"], events[0]["reason"]) == ("explicit", None)  # no words given
    assert (message.json()["status"], message.json()["activation"]["kind"]) == (
        "accepted",
        "explicit",
    )

    assert api.delete(f"/v1/tools/{tool['id']}").status_code == 204
    wait_for(lambda: sub.on(topic)[-1].payload == b"", 1.0, "the archive's empty message")
    assert _retained_now(broker, prefix, tool["id"]) is None  # cleared for late subscribers
    sub.close()


@one_backend
def test_a_frames_activation_is_retained_on_its_topic_as_get_frame_serves_it(
    api: Api, broker: Broker, prefix: str, tmp_path: Path, publishers: list[Publisher]
) -> None:
    """Contract v1.4: {prefix}/frames/{frame_id}/frame, retained, as the tools' topic."""
    robot = api.robot("r-frames", vendor="KUKA")
    made = api.post(
        f"/v1/robots/{robot['id']}/frames", {"name": "fixture-a", "kind": "base", "slot": 2}
    )
    assert made.status_code == 201, made.text
    frame_id = made.json()["id"]
    assert add_frame_version(frame_id, [500.0, 10.0, 0.0]) == 1
    sub = Subscriber(broker, prefix)
    _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: _online(sub), 30, "the publisher's status online")
    topic = f"frames/{frame_id}/frame"
    wait_for(lambda: _outbox_size() == 0, 10, "the changes made before it started sent")
    wait_for(lambda: bool(sub.on(topic)), 5, "the frame's state sent")
    assert sub.on(topic)[-1].payload == b""  # no active version yet: cleared

    activated = api.post(
        f"/v1/frames/{frame_id}/versions/1/activate",
        {"reason": "taught on the pendant"},
        scope="calibrate",
    )
    assert activated.status_code == 200, activated.text
    at = time.monotonic()
    wait_for(lambda: sub.on(topic)[-1].payload != b"", 1.0, "the retained message within 1 s")
    message = sub.on(topic)[-1]
    assert message.at - at < 1.0
    served = api.get(f"/v1/frames/{frame_id}/frame")
    assert {k: v for k, v in message.json().items() if k not in ("status", "activation")} == {
        **served.json(),
        "etag": served.headers["ETag"],
    }
    assert message.json()["status"] == "accepted"
    assert (message.json()["activation"]["kind"], message.json()["activation"]["reason"]) == (
        "explicit",
        "taught on the pendant",
    )
    late = Subscriber(broker, prefix)
    try:
        wait_for(lambda: any(m.retain for m in late.on(topic)), 5, "the retained message")
        assert [m for m in late.on(topic) if m.retain][-1].payload == message.payload
    finally:
        late.close()
    events = [e for e in sub.events() if e.get("frame_id") == frame_id]
    assert "version.activate" in [e["action"] for e in events]
    assert api.delete(f"/v1/frames/{frame_id}").status_code == 204
    wait_for(lambda: sub.on(topic)[-1].payload == b"", 1.0, "the archive's empty message")
    sub.close()


def test_events_arrive_once_each_in_commit_order_per_tool(
    api: Api, broker: Broker, prefix: str, tmp_path: Path, publishers: list[Publisher]
) -> None:
    robot = api.robot("r-order")
    tools = [_tool_with_versions(api, robot["id"], f"t{i}", 3) for i in range(3)]
    sub = Subscriber(broker, prefix)
    _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: _online(sub), 30, "the publisher's status online")
    for round_ in range(4):
        for tool in tools:
            _activate(api, tool["id"], 1 + (round_ % 3))
    api.manual(tools[0]["id"], [9.0, 9.0, 309.0])  # a calibration stored (and activated)
    ids = {t["id"] for t in tools}
    expected = _audit_order(ids)
    wait_for(lambda: len(_event_keys(sub, ids)) >= len(expected), 10, "every event")
    time.sleep(0.5)  # nothing more arrives
    got = _event_keys(sub, ids)
    assert len(got) == len(set(got)) == len(expected)  # once each
    for tool in tools:
        assert _per_tool(got, tool["id"]) == _per_tool(expected, tool["id"])
    for tool in tools:
        assert _retained_now(broker, prefix, tool["id"]) is not None
        retained = sub.on(f"tools/{tool['id']}/tcp")[-1].json()
        assert retained == _served(api, tool["id"])
    wait_for(lambda: _outbox_size() == 0, 5, "the delivered rows pruned (kept 0 s)")
    sub.close()


def _outbox_size() -> int:
    with session_scope(write=False) as session:
        return len(list(session.scalars(select(OutboxMessage.id))))


@one_backend
def test_broker_killed_twenty_activations_then_restarted(
    api: Api, tmp_path: Path, prefix: str, publishers: list[Publisher]
) -> None:
    broker = Broker(tmp_path, persist=True)  # the test subscriber's session survives it
    broker.start()
    try:
        robot = api.robot("r-broker")
        tools = [_tool_with_versions(api, robot["id"], f"t{i}", 2) for i in range(4)]
        sub = Subscriber(broker, prefix, persistent=True)
        _publisher(publishers, tmp_path, api, broker, prefix)
        wait_for(lambda: _online(sub), 30, "the publisher's status online")
        wait_for(lambda: _outbox_size() == 0, 10, "the changes made before it started sent")
        time.sleep(1.5)  # the broker saved the subscriber's session (autosave_interval 1)
        ids = {t["id"] for t in tools}
        before = set(_event_keys(sub, ids))

        broker.kill()
        for i in range(20):
            tool = tools[i % 4]
            _activate(api, tool["id"], 1 + (i // 4) % 2)
        time.sleep(0.5)
        broker.start()

        expected = [k for k in _audit_order(ids) if k not in before]
        assert len(expected) == 20
        wait_for(
            lambda: set(expected) <= set(_event_keys(sub, ids)), 60, "all 20 events after restart"
        )
        got = _first_occurrences([k for k in _event_keys(sub, ids) if k not in before])
        for tool in tools:
            assert _per_tool(got, tool["id"]) == _per_tool(expected, tool["id"])
            retained = _retained_now(broker, prefix, tool["id"])
            assert retained is not None
            assert json.loads(retained) == _served(api, tool["id"])
        sub.close()
    finally:
        broker.stop()


@one_backend
def test_a_restarted_broker_without_persistence_gets_every_tool_state_again(
    api: Api, broker: Broker, prefix: str, tmp_path: Path, publishers: list[Publisher]
) -> None:
    robot = api.robot("r-resync")
    tools = [_tool_with_versions(api, robot["id"], f"t{i}", 1) for i in range(3)]
    for tool in tools:
        _activate(api, tool["id"], 1)
    sub = Subscriber(broker, prefix)
    _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: _online(sub), 30, "the publisher's status online")
    sub.close()
    broker.kill()  # its retained messages are gone with it
    broker.start()
    watcher = Subscriber(broker, prefix)
    wait_for(lambda: _online(watcher), 60, "the publisher back online")
    watcher.close()
    time.sleep(1.0)
    for tool in tools:
        retained = _retained_now(broker, prefix, tool["id"])
        assert retained is not None, "a tool unchanged while the broker was down was lost"
        assert json.loads(retained) == _served(api, tool["id"])


def test_publisher_killed_mid_drain_and_restarted(
    api: Api, broker: Broker, prefix: str, tmp_path: Path, publishers: list[Publisher]
) -> None:
    robot = api.robot("r-kill")
    tools = [_tool_with_versions(api, robot["id"], f"t{i}", 2) for i in range(4)]
    ids = {t["id"] for t in tools}
    already = len(_audit_order(ids))
    for i in range(20):
        _activate(api, tools[i % 4]["id"], 1 + (i // 4) % 2)
    expected = _audit_order(ids)
    sub = Subscriber(broker, prefix)
    # One row a batch: the drain takes long enough to be killed in the middle of it.
    first = _publisher(publishers, tmp_path, api, broker, prefix, TCPCAL_PUBLISH_BATCH="1")
    wait_for(lambda: len(_event_keys(sub, ids)) >= already + 3, 60, "the drain under way")
    first.kill()
    delivered_before_kill = len(_event_keys(sub, ids))
    assert delivered_before_kill < len(expected), "the drain had finished before the kill"
    _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: set(expected) <= set(_event_keys(sub, ids)), 60, "every event")
    got = _first_occurrences(_event_keys(sub, ids))
    for tool in tools:
        assert _per_tool(got, tool["id"]) == _per_tool(expected, tool["id"])
        retained = _retained_now(broker, prefix, tool["id"])
        assert retained is not None
        assert json.loads(retained) == _served(api, tool["id"])
    assert _online(sub)
    sub.close()


def test_two_publishers_one_publishes_and_the_other_takes_over(
    api: Api, broker: Broker, prefix: str, tmp_path: Path, publishers: list[Publisher]
) -> None:
    robot = api.robot("r-two")
    tool = _tool_with_versions(api, robot["id"], "t", 2)
    sub = Subscriber(broker, prefix)
    first = _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: _online(sub), 30, "the first publisher online")
    second = _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: "waiting" in second.output(), 30, "the second publisher waiting")
    for i in range(6):
        _activate(api, tool["id"], 1 + i % 2)
    ids = {tool["id"]}
    expected = _audit_order(ids)
    wait_for(lambda: len(_event_keys(sub, ids)) >= len(expected), 10, "every event")
    time.sleep(1.0)
    got = _event_keys(sub, ids)
    assert got == expected  # once each: only one publisher sent them
    assert "publishing to mqtt" not in second.output()

    seconds = first.terminate()
    assert seconds < 1.0, f"SIGTERM took {seconds:.2f} s"
    assert first.wait(1) == 0
    wait_for(lambda: "publishing to mqtt" in second.output(), 10, "the second one taking over")
    _activate(api, tool["id"], 1)
    expected = _audit_order(ids)
    wait_for(lambda: _event_keys(sub, ids) == expected, 5, "the change sent by the second")
    assert _online(sub)
    sub.close()


@one_backend
def test_sigterm_stops_within_a_second_and_says_offline(
    api: Api, broker: Broker, prefix: str, tmp_path: Path, publishers: list[Publisher]
) -> None:
    sub = Subscriber(broker, prefix)
    publisher = _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: _online(sub), 30, "the publisher online")
    seconds = publisher.terminate()
    assert seconds < 1.0, f"SIGTERM took {seconds:.2f} s: {publisher.output()}"
    assert publisher.wait(1) == 0
    wait_for(lambda: sub.on("status")[-1].payload == b"offline", 2, "status offline")
    late = Subscriber(broker, prefix)
    time.sleep(0.3)
    assert [m.payload for m in late.on("status") if m.retain] == [b"offline"]
    late.close()
    sub.close()


@one_backend
def test_a_forced_out_of_tolerance_activation_says_so_retained_and_in_its_event(
    api: Api, broker: Broker, prefix: str, tmp_path: Path, publishers: list[Publisher]
) -> None:
    """Issue 37: a subscribing cell must tell that it runs an out-of-tolerance TCP, and why;
    and that a rollback took it back to an accepted one."""
    robot = api.robot("r-forced")
    tool = api.tool(robot["id"], "torch")
    api.manual(tool["id"], [0.0, 0.0, 150.0])
    bad = out_of_tolerance_version(api, tool["id"])
    sub = Subscriber(broker, prefix)
    _publisher(publishers, tmp_path, api, broker, prefix)
    wait_for(lambda: _online(sub), 30, "the publisher's status online")
    topic = f"tools/{tool['id']}/tcp"
    why = "probe bent, interim TCP until the new one is calibrated"

    force(api, tool["id"], bad, why)
    wait_for(lambda: _version(sub, topic) == bad, 1.0, "the forced version")
    retained = sub.on(topic)[-1].json()
    assert retained["status"] == "out_of_tolerance"
    assert (retained["activation"]["kind"], retained["activation"]["reason"]) == ("forced", why)
    assert retained["activation"]["by"] == "test-calibrate"
    assert retained == _served(api, tool["id"])
    late = _retained_now(broker, prefix, tool["id"])
    assert late is not None
    assert json.loads(late)["status"] == "out_of_tolerance"  # a cell subscribing later too
    wait_for(lambda: _actions(sub, tool["id"])[-1:] == ["version.activate"], 2, "the event")
    event = [e for e in sub.events() if e["tool_id"] == tool["id"]][-1]
    assert (event["version"], event["kind"], event["reason"]) == (bad, "forced", why)

    rollback(api, tool["id"])
    wait_for(lambda: _version(sub, topic) == 1, 1.0, "the rollback")
    retained = sub.on(topic)[-1].json()
    assert retained["status"] == "accepted"
    assert (retained["activation"]["kind"], retained["activation"]["reason"]) == (
        "rollback",
        None,
    )
    assert retained == _served(api, tool["id"])
    wait_for(lambda: _actions(sub, tool["id"])[-1:] == ["version.rollback"], 2, "the event")
    event = [e for e in sub.events() if e["tool_id"] == tool["id"]][-1]
    assert (event["version"], event["kind"], event["reason"]) == (1, "rollback", None)
    created = [e for e in sub.events() if e["action"] == "robot.create"]
    assert [(e["kind"], e["reason"]) for e in created] == [(None, None)]  # not an activation
    sub.close()


def _version(sub: Subscriber, topic: str) -> int | None:
    """The version of the last message on a tool's topic (None before any, or cleared)."""
    received = sub.on(topic)
    if not received or not received[-1].payload:
        return None
    return int(received[-1].json()["version"])


def _actions(sub: Subscriber, tool_id: str) -> list[str]:
    return [e["action"] for e in sub.events() if e["tool_id"] == tool_id]
