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
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from app.jsontypes import JsonObject
from app.words import AuditAction


class SinkError(Exception):
    """A sink cannot start: wrong configuration or an unreachable peer (the message says
    which, and what to do)."""


@dataclass(frozen=True, slots=True)
class Message:
    """One outbox row: an event for the plant (`event` is the published JSON object:
    action, tool_id, robot_id, version, actor, at, request_id)."""

    id: int
    action: AuditAction
    robot_id: str | None
    tool_id: str | None
    event: JsonObject


@dataclass(frozen=True, slots=True)
class PublishedTool:
    """What is published of one tool now (a batch's state of it; not app.words.ToolState, a
    tool's controller state): `document` is what GET /v1/tools/{id}/tcp serves,
    with its `etag`, the active version's `status` and its `activation` added (source.py);
    None when the tool is archived or has no active version (MQTT clears the retained
    message)."""

    tool_id: str
    robot_id: str
    tool_name: str
    robot_name: str
    archived: bool
    document: JsonObject | None


@dataclass(frozen=True, slots=True)
class Batch:
    """What one `deliver` call sends: messages in id order, then the current state of every
    tool they concern (or, with `full`, of every live tool, and no messages)."""

    messages: Sequence[Message] = ()
    states: Sequence[PublishedTool] = ()
    full: bool = False


class Sink(Protocol):
    """A publisher target (see the module's docstring for the contract)."""

    name: str

    def open(self, stopping: threading.Event) -> None: ...

    def connection_id(self) -> int: ...

    def deliver(self, batch: Batch) -> bool: ...

    def close(self) -> None: ...
