"""The OPC UA server as a sink of the publisher (app.publish.runner): started with it,
refreshed from the database for every robot a batch concerns, so its values follow the
database within the runner's poll interval.

A batch only says which robots to read again, never what to show: the values are read by
one path (app.services.fleet.plant) at start-up and after every batch, so a message delivered
twice, late or out of order still leaves the address space equal to the database, and
ControllerState, UpdatedAt and a robot that has no tool or frame yet are shown as well.

asyncua is asyncio; the runner is a thread that calls `deliver` and waits for the answer.
The server runs on an event loop in a thread of its own (so sessions, subscriptions and
keep-alives are served while the runner reads the database), and each update is handed to
that loop and awaited with a timeout.
"""

from __future__ import annotations

import asyncio
import hmac
import logging
import threading
from collections.abc import Callable, Coroutine, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol, TypeVar

from sqlalchemy import select

from app.errors import DomainError
from app.publish.opcua import KeyCheck, PlantOpcUaServer, parse_endpoint
from app.publish.opcua_certs import ServerCertificate, server_certificate
from app.security.auth import authenticate_key
from app.services.fleet.plant import PlantRobot, plant_robots
from app.services.subjects import SUBJECTS
from app.storage.db import session_scope

log = logging.getLogger(__name__)
T = TypeVar("T")

#: How long one update of the address space may take before the batch counts as failed.
UPDATE_TIMEOUT_S = 10.0
#: How long closing waits for the server to end its clients' sessions: the publisher exits
#: within a second of SIGTERM (docs/publishing.md), and a session the server has not ended by
#: then ends with the process (the operating system closes its socket).
STOP_TIMEOUT_S = 0.4
START_TIMEOUT_S = 30.0


class _Named(Protocol):
    """What the sink reads of a message or a state: the robot, and the subjects (by key)."""

    @property
    def robot_id(self) -> str | None: ...
    @property
    def ids(self) -> Mapping[str, str | None]: ...


class _Located(Protocol):
    """What the sink reads of a state: its robot (every state has one)."""

    @property
    def robot_id(self) -> str: ...


class BatchLike(Protocol):
    """What the sink reads of the runner's batch (app.publish.sink.Batch)."""

    @property
    def messages(self) -> Sequence[_Named]: ...
    @property
    def states(self) -> Sequence[_Located]: ...
    @property
    def full(self) -> bool: ...


@dataclass(frozen=True, slots=True)
class _Robot:
    """A state's robot (a state names its robot always)."""

    robot_id: str
    ids: Mapping[str, str | None]


def key_may_read(username: str, password: str) -> bool:
    """True when `password` is a live API key of scope read or above, named `username`, and
    not limited to cells (checked by app.security.auth, as an Authorization header is)."""
    try:
        with session_scope(write=False) as session:
            principal = authenticate_key(session, password, required="read")
    except DomainError:
        return False
    if getattr(principal, "cells", None):
        # The address space shows the whole fleet: a key limited to some cells must not see
        # it (the API shows such a key only its cells; one view per session is not built).
        log.warning("OPC UA sign-in refused for %r: the key is limited to cells", username)
        return False
    return hmac.compare_digest(principal.name.encode(), username.encode())


def read_fleet() -> list[PlantRobot]:
    """Every live robot and what it holds as the plant sees them."""
    with session_scope(write=False) as session:
        return plant_robots(session)


#: Subject ids given without their robot, by the subject's key ("tool_id").
ByKey = dict[str, set[str]]


def read_robots(robot_ids: Iterable[str], by_key: ByKey) -> dict[str, PlantRobot | None]:
    """The robots named, and those of the subjects named, as the plant sees them now (None:
    archived or unknown)."""
    with session_scope(write=False) as session:
        ids = set(robot_ids)
        for subject in SUBJECTS:
            named = by_key.get(subject.key)
            if named:
                table = subject.table
                ids.update(session.scalars(select(table.c.robot_id).where(table.c.id.in_(named))))
        found: dict[str, PlantRobot | None] = {}
        for robot_id in sorted(ids):
            robots = plant_robots(session, robot_id=robot_id)
            found[robot_id] = robots[0] if robots else None
        return found


def robots_concerned(items: Iterable[_Named]) -> tuple[set[str], ByKey]:
    """(robot ids, ids of subjects given without their robot, by key) of messages and
    states."""
    robots: set[str] = set()
    by_key: ByKey = {}
    for item in items:
        if item.robot_id:
            robots.add(item.robot_id)
            continue
        for key, subject_id in item.ids.items():
            if subject_id:
                by_key.setdefault(key, set()).add(subject_id)
    return robots, by_key


class OpcUaPlantSink:
    """The publisher's OPC UA sink (app.publish.sink.Sink): an asyncua server on its own
    event loop thread, kept equal to the database."""

    name = "opcua"

    def __init__(
        self,
        endpoint: str,
        *,
        anonymous: bool,
        certificate: ServerCertificate | None = None,
        check: KeyCheck = key_may_read,
        fleet: Callable[[], list[PlantRobot]] = read_fleet,
        robots: Callable[[set[str], ByKey], dict[str, PlantRobot | None]] = read_robots,
    ) -> None:
        self.server = PlantOpcUaServer(
            endpoint, check=check, anonymous=anonymous, certificate=certificate
        )
        self._fleet = fleet
        self._robots = robots
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None

    def open(self, stopping: threading.Event) -> None:
        """Listen on the endpoint and show the whole fleet; OpcUaStartError (a SinkError)
        with the reason when the endpoint cannot be served."""
        loop = asyncio.new_event_loop()
        self._loop = loop
        self._thread = threading.Thread(target=loop.run_forever, name="opcua", daemon=True)
        self._thread.start()
        try:
            self._call(self.server.start(self._fleet()), START_TIMEOUT_S)
        except BaseException:  # not listening: no loop left behind either
            self._stop_loop()
            raise
        log.info("OPC UA server listening at %s", self.server.endpoint.url)

    def connection_id(self) -> int:
        """1: the address space is never lost while the sink is open."""
        return 1

    def deliver(self, batch: BatchLike) -> bool:
        """Refresh every robot the batch concerns; False when the update failed (the runner
        hands the batch again)."""
        if batch.full:
            # The whole fleet was read when the sink opened, and every change since is an
            # undelivered outbox row (rows are marked only once this sink accepted them).
            return True
        located = [_Robot(s.robot_id, {}) for s in batch.states]
        robot_ids, by_key = robots_concerned([*batch.messages, *located])
        if not robot_ids and not by_key:
            return True
        try:
            robots = self._robots(robot_ids, by_key)
            for robot_id, robot in robots.items():
                self._call(self.server.replace_robot(robot_id, robot), UPDATE_TIMEOUT_S)
        except Exception:  # any failure of one update: the runner retries the batch
            log.exception("OPC UA update failed; the batch will be sent again")
            return False
        return True

    def close(self) -> None:
        """Close the clients' sessions and stop listening."""
        if self._loop is None:
            return
        try:
            self._call(self.server.stop(), STOP_TIMEOUT_S)
        except TimeoutError:
            log.warning(
                "OPC UA sessions not ended within %.1f s; they end with the process", STOP_TIMEOUT_S
            )
        finally:
            self._stop_loop()

    def _call(self, coro: Coroutine[object, object, T], timeout: float) -> T:
        assert self._loop is not None, "open() first"
        return asyncio.run_coroutine_threadsafe(coro, self._loop).result(timeout)

    def _stop_loop(self) -> None:
        loop, thread = self._loop, self._thread
        self._loop = self._thread = None
        if loop is not None:
            loop.call_soon_threadsafe(loop.stop)
        if thread is not None:
            thread.join(timeout=5)
        if loop is not None and not loop.is_running():
            loop.close()


def opcua_sink(
    endpoint: str, *, anonymous: bool, certificate: str | None, private_key: str | None
) -> OpcUaPlantSink:
    """The sink TCPCAL_OPCUA_* configure (SinkError for a malformed endpoint or unreadable
    certificate files: before the publisher waits for its lock)."""
    host = parse_endpoint(endpoint).host
    cert = server_certificate(certificate, private_key, host=host)
    return OpcUaPlantSink(endpoint, anonymous=anonymous, certificate=cert)
