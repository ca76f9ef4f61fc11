"""What a publisher target implements, and what the runner hands it.

The runner (app.publish.runner) owns the database; a sink owns one connection to the plant
(an MQTT broker, an OPC UA server's address space). The contract, for any sink:

- `open()` connects or binds, and raises `SinkError` with a sentence an operator can act on
  when the configuration is wrong (unreachable broker, refused credentials, malformed URL,
  port in use): the runner prints it and exits non-zero, never publishing silently.
- `deliver(batch)` sends the batch and returns True only when every message and state in
  it is accepted (MQTT: every PUBACK received); False when the connection is down or was
  lost during the batch: the runner keeps the rows undelivered and hands the same rows (and
  fresh states) again later, so a sink receives a message at least once, and a tool's
  messages in order. It must not block for longer than about a second at a time without
  checking `stopping` (the runner stops within a second of SIGTERM).
- `connection_id()`: a number that changes at every (re)connection (an OPC UA server that
  never loses its address space: 1 once open). For each new value the runner first sends
  the state of every live tool, in batches with `full=True` and no messages (the broker may
  have lost its retained messages; a new address space is empty), then goes on with the
  outbox.
- `close()` disconnects cleanly (MQTT: publishes `offline`).

Messages come in `id` order (commit order per tool: app.services.audit.outbox); the states of a
batch are read from the database after its messages, so the last state a sink sees of a
tool is the tool's current one (the retained topic always ends at the current state).
"""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

from app.jsontypes import JsonObject
from app.services.lifecycle.subject import AnySubject
from app.words import AuditAction


class SinkError(Exception):
    """A sink cannot start: wrong configuration or an unreachable peer (the message says
    which, and what to do)."""


@dataclass(frozen=True, slots=True)
class Message:
    """One outbox row: an event for the plant (`event` is the published JSON object:
    action, tool_id, robot_id, version, actor, at, request_id); `ids`, the subject it names
    by each subject's key (app.storage.models.SUBJECT_KEYS: {"tool_id": ...}), None for a
    key it does not name."""

    id: int
    action: AuditAction
    robot_id: str | None
    ids: Mapping[str, str | None]
    event: JsonObject


@dataclass(frozen=True, slots=True)
class PublishedSubject:
    """What is published of one calibrated subject now (a batch's state of it: a tool's, of
    `subject` app.services.tools.subject.TOOL; not app.words.ToolState, a tool's controller
    state): `document` is what its read route serves (a tool's GET /v1/tools/{id}/tcp),
    with its `etag`, the active version's `status` and its `activation` added (source.py);
    None when it is archived or has no active version (MQTT clears the retained message)."""

    subject: AnySubject
    subject_id: str
    robot_id: str
    name: str
    robot_name: str
    archived: bool
    document: JsonObject | None


@dataclass(frozen=True, slots=True)
class Batch:
    """What one `deliver` call sends: messages in id order, then the current state of every
    subject they concern (or, with `full`, of every live one, and no messages)."""

    messages: Sequence[Message] = ()
    states: Sequence[PublishedSubject] = ()
    full: bool = False


class Sink(Protocol):
    """A publisher target (see the module's docstring for the contract)."""

    name: str

    def open(self, stopping: threading.Event) -> None: ...

    def connection_id(self) -> int: ...

    def deliver(self, batch: Batch) -> bool: ...

    def close(self) -> None: ...
