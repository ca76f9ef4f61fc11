"""Re-check commands over MQTT (issue 41), against a real Mosquitto the test starts and
`tcpcal publish` as a child process with TCPCAL_MQTT_COMMANDS=true, the robot a KUKA
simulator (tests/controllers/kuka_sim.py) standing with the tool's moved tip at the
reference point. A test PLC (an MQTT 5 paho client, tests/publish/mqtt_harness.Commander)
sends `{prefix}/commands/recheck` with the key in the user property `authorization` and
reads `{prefix}/replies/{request_id}`. What the service does with the touch (the correction
within 0.02 mm, each controller) is tests/api/test_recheck_controllers.py's; here: the
command reaches it, once, as the HTTP call does, and its answer comes back."""

from __future__ import annotations

import json
import os
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.api.controller_rigs import rig
from tests.api.test_capture_controllers import SETUPS, Cell
from tests.api.test_recheck_controllers import (
    ACTIVE_POSITION,
    MOVED,
    stand_at_reference,
    tool_at_reference,
)
from tests.api.touches import row_counts
from tests.conftest import Api, one_backend
from tests.polling import wait_for
from tests.publish.mqtt_harness import Broker, Commander, Publisher, needs_mosquitto

pytestmark = [needs_mosquitto, pytest.mark.live, one_backend]

#: What a command may change, and what a refused or repeated one must leave as it was.
TABLES = (
    "tcp_versions",
    "activations",
    "calibrations",
    "deployments",
    "audit_events",
    "idempotency_records",
)


@pytest.fixture
def kuka() -> Iterator[Cell]:
    with rig("kuka_kvp") as r:
        yield SETUPS["kuka_kvp"](r)


@pytest.fixture
def publisher(api: Api, broker: Broker, prefix: str, tmp_path: Path) -> Iterator[Publisher]:
    database_url = os.environ["TCPCAL_DATABASE_URL"]  # the test database (api's db fixture)
    started = Publisher(tmp_path, database_url, broker.url(), prefix, TCPCAL_MQTT_COMMANDS="true")
    yield started.start()
    started.kill()


@pytest.fixture
def plc(publisher: Publisher, broker: Broker, prefix: str) -> Iterator[Commander]:
    commander = Commander(broker, prefix)
    try:
        _wait_answering(commander)
        yield commander
    finally:
        commander.close()


def _wait_answering(plc: Commander) -> None:
    """Until the publisher answers: a command that is not JSON, sent until its 422 comes back
    on replies/_invalid (the publisher subscribes once connected, after the migration check)."""

    before = len(plc.on("_invalid"))

    def answered() -> bool:
        if len(plc.on("_invalid")) > before:
            return True
        if plc.client.is_connected():  # (the PLC's own reconnection after a broker restart)
            plc.send(b"{not json", "none")
        return False

    wait_for(answered, 30, "the publisher answering commands")
    payload, said = plc.on("_invalid")[before]
    problem = json.loads(payload)
    assert (problem["status"], said["status"]) == (422, "422")
    assert problem["errors"][0]["loc"] == ["body"]
    assert "not JSON" in problem["detail"]


def _reply(plc: Commander, request_id: str, timeout: float = 20) -> tuple[Any, dict[str, str]]:
    wait_for(lambda: bool(plc.on(request_id)), timeout, f"the reply to {request_id}")
    payload, said = plc.on(request_id)[0]
    return json.loads(payload), said


def _command(tool_id: str, point_id: str, request_id: str, **extra: Any) -> dict[str, Any]:
    return {
        "request_id": request_id,
        "tool_id": tool_id,
        "reference_point_id": point_id,
        "correct": "within_limits",
        **extra,
    }


def test_a_command_is_answered_once_and_a_repeat_gets_the_first_answer(
    api: Api, kuka: Cell, publisher: Publisher, plc: Commander
) -> None:
    tool, point_id = tool_at_reference(api, kuka.rig)
    truth = np.asarray(ACTIVE_POSITION) + MOVED
    stand_at_reference(kuka, truth)
    request_id = f"plc-cell4-{uuid.uuid4().hex[:8]}"
    command = _command(tool["id"], point_id, request_id, reason="collision input, cell 4")
    plc.send(command, api.keys["calibrate"])
    check, said = _reply(plc, request_id)
    assert said == {"status": "201"}
    assert check["verdict"] == "corrected", check
    assert check["correction"]["version"] == 2
    np.testing.assert_allclose(check["correction"]["delta_mm"], MOVED, atol=0.02)
    assert check["correction"]["deployment"]["status"] == "verified"
    assert check["checked_by"] == "test-calibrate"  # the key's name, as over HTTP
    served = api.get(f"/v1/tools/{tool['id']}/tcp").json()
    assert served["version"] == 2
    assert np.linalg.norm(np.asarray(served["tcp"]["position_mm"]) - truth) < 0.02
    last = api.get(f"/v1/tools/{tool['id']}/versions").json()["activations"][-1]
    assert (last["version"], last["reason"], last["reason_text"]) == (
        2,
        "check_correction",
        "collision input, cell 4",
    )
    time.sleep(0.5)
    assert len(plc.on(request_id)) == 1  # answered once
    counts, native = row_counts(TABLES), kuka.rig.native()

    plc.send(command, api.keys["calibrate"])  # the PLC lost the reply and asks again
    wait_for(lambda: len(plc.on(request_id)) == 2, 20, "the repeated command's reply")
    (first, _), (again, said_again) = plc.on(request_id)
    assert again == first  # byte for byte
    assert said_again == {"status": "201", "replayed": "true"}
    assert row_counts(TABLES) == counts
    assert kuka.rig.native() == native
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["version"] == 2

    # the same request_id with another body is the HTTP Idempotency-Key's conflict
    plc.send({**command, "correct": "never"}, api.keys["calibrate"])
    wait_for(lambda: len(plc.on(request_id)) == 3, 20, "the changed command's reply")
    conflict, said_conflict = plc.on(request_id)[2]
    assert said_conflict == {"status": "409"}
    assert json.loads(conflict)["type"].endswith("/idempotency-key-reused")
    assert row_counts(TABLES) == counts

    assert publisher.terminate() < 1.0  # docs/publishing.md: within a second of SIGTERM
    _never_logged(api, publisher, plc)


def test_a_read_key_a_missing_key_and_a_bad_command_are_refused_and_change_nothing(
    api: Api, kuka: Cell, publisher: Publisher, plc: Commander
) -> None:
    tool, point_id = tool_at_reference(api, kuka.rig)
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    counts, native = row_counts(TABLES), kuka.rig.native()

    plc.send(_command(tool["id"], point_id, "read-1"), api.keys["read"])
    problem, said = _reply(plc, "read-1")
    assert (problem["status"], said["status"]) == (403, "403")
    assert problem["type"].endswith("/forbidden")
    assert "this key has scope 'read'; this operation needs 'calibrate'" in problem["detail"]

    plc.send(_command(tool["id"], point_id, "nokey-1"), None)
    problem, said = _reply(plc, "nokey-1")
    assert (problem["status"], said["status"]) == (401, "401")
    assert "user property 'authorization'" in problem["detail"]

    plc.send(_command(tool["id"], point_id, "wrong-1"), "Bearer tcpcal_not-a-key")
    problem, _ = _reply(plc, "wrong-1")
    assert problem["status"] == 401
    assert "unknown or revoked" in problem["detail"]

    no_point = {"request_id": "bad-1", "tool_id": tool["id"], "correct": "sometimes"}
    plc.send(no_point, api.keys["calibrate"])
    problem, said = _reply(plc, "bad-1")
    assert (problem["status"], said["status"]) == (422, "422")
    locs = [e["loc"] for e in problem["errors"]]
    assert ["body", "reference_point_id"] in locs
    assert ["body", "correct"] in locs
    assert problem["detail"].startswith("body.")

    typed = {**_command(tool["id"], point_id, "typed-1"), "format": "matrix", "poses": []}
    plc.send(typed, api.keys["calibrate"])
    problem, _ = _reply(plc, "typed-1")
    assert problem["status"] == 422
    assert ["body", "format"] in [e["loc"] for e in problem["errors"]]

    plc.send({"tool_id": tool["id"], "reference_point_id": point_id}, api.keys["calibrate"])
    unaddressed = {"loc": ["body", "request_id"], "msg": "Field required: it names the reply topic"}

    def refused_on_invalid() -> bool:  # (besides the probes' "not JSON", fixture plc)
        return any(json.loads(p)["errors"] == [unaddressed] for p, _ in plc.on("_invalid"))

    wait_for(refused_on_invalid, 20, "the reply to a command without a request_id")

    assert row_counts(TABLES) == counts
    assert kuka.rig.native() == native
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["version"] == 1
    _never_logged(api, publisher, plc)

    # a command under way on a controller that stopped answering (10 s timeout) does not
    # hold up SIGTERM (docs/publishing.md: within a second); it is abandoned unanswered
    slow = kuka.rig.controller_body(timeout_s=10.0)
    put = api.request("PUT", f"/v1/robots/{tool['robot_id']}/controller", "admin", json=slow)
    assert put.status_code == 200, put.text
    kuka.rig.sim.stalled = True
    connected = kuka.rig.sim.connections_accepted
    plc.send(_command(tool["id"], point_id, "stuck-1"), api.keys["calibrate"])
    wait_for(lambda: kuka.rig.sim.connections_accepted > connected, 20, "the command at the KRC")
    time.sleep(0.3)  # (its read sent, its answer awaited)
    assert publisher.terminate() < 1.0
    assert plc.on("stuck-1") == []


def test_commands_are_answered_again_after_the_broker_restarts(
    api: Api, broker: Broker, publisher: Publisher, plc: Commander
) -> None:
    """The publisher's session is clean: its subscription is made again at each connection
    (a broker restarted without persistence remembers none)."""
    broker.kill()
    broker.start()
    _wait_answering(plc)  # reconnected (backoff 1 s), subscribed again, answering
    plc.send({"request_id": "after-restart", "tool_id": "x", "reference_point_id": "y"}, None)
    problem, said = _reply(plc, "after-restart")
    assert (problem["status"], said["status"]) == (401, "401")


def _never_logged(api: Api, publisher: Publisher, plc: Commander) -> None:
    """No key sent in a command appears in the publisher's log or in any reply."""
    output = publisher.output()
    assert "recheck command" in output  # the commands are logged: by the key's name only
    replies = b"".join(payload for _, payload, _ in plc.replies).decode()
    for key in (api.keys["calibrate"], api.keys["read"], "tcpcal_not-a-key"):
        assert key not in output
        assert key not in replies
