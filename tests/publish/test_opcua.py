"""The publisher's OPC UA server, as plant clients see it.

`tcpcal publish` runs as its own process with TCPCAL_OPCUA_ENDPOINT on a free loopback port;
the changes are made through the API (in-process) on the same database. The main test's
client is node-opcua (another implementation than the server's asyncua), run by Node from
tests/opcua_client (`npm ci` there; `make test` does it); the quicker checks of the address
space's life use asyncua's client.
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import queue
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest
from asyncua import ua
from asyncua.client.client import Client
from asyncua.sync import Client as SyncClient
from asyncua.ua.uaerrors import UaError, UaStatusCodeError
from prometheus_client.parser import text_string_to_metric_families

from tests.conftest import Api, Database, one_backend

REPO = Path(__file__).resolve().parents[2]
NODE_CLIENT = REPO / "tests" / "opcua_client"
TCPCAL = Path(sys.executable).parent / "tcpcal"
NS = "urn:tcpcal"

# Every test here runs `tcpcal publish` as a process of its own.
pytestmark = pytest.mark.live


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _env(db: Database, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("TCPCAL_")}
    env.update(TCPCAL_DATABASE_URL=db.url, PYTHONPATH=str(REPO), TCPCAL_PUBLISH_POLL_S="0.1")
    env.update(extra)
    return env


@contextmanager
def publisher(db: Database, **extra: str) -> Iterator[str]:
    """`tcpcal publish` serving OPC UA on a free port; yields the endpoint once it listens."""
    port = _free_port()
    endpoint = f"opc.tcp://127.0.0.1:{port}/tcpcal/"
    env = _env(db, TCPCAL_OPCUA_ENDPOINT=endpoint, **extra)
    output = tempfile.TemporaryFile()  # noqa: SIM115 (closed below)
    proc = subprocess.Popen(
        [str(TCPCAL), "publish"], cwd=REPO, env=env, stdout=output, stderr=subprocess.STDOUT
    )
    try:
        deadline = time.monotonic() + 60
        while True:
            if proc.poll() is not None:
                output.seek(0)
                out = output.read().decode()
                raise AssertionError(f"tcpcal publish exited {proc.returncode}:\n{out}")
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
                break
            except OSError:
                if time.monotonic() > deadline:
                    output.seek(0)
                    raise AssertionError(
                        f"tcpcal publish did not listen within 60 s:\n{output.read().decode()}"
                    ) from None
                time.sleep(0.1)
        yield endpoint
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        output.close()


def _node() -> str:
    node = shutil.which("node")
    ready = node is not None and (NODE_CLIENT / "node_modules" / "node-opcua").is_dir()
    if ready and node:
        return node
    if os.environ.get("CI") or os.environ.get("TCPCAL_REQUIRE_BROWSER"):
        pytest.fail("node and tests/opcua_client/node_modules are needed: npm ci there")
    pytest.skip("node-opcua not installed (cd tests/opcua_client && npm ci)")


class NodeClient:
    """The node-opcua script, its JSON lines read as they come with the time each came."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen(
            [_node(), str(NODE_CLIENT / "client.js"), *args],
            cwd=NODE_CLIENT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.lines: queue.Queue[tuple[float, dict[str, Any]]] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for raw in self.proc.stdout:
            if raw.startswith(b"{"):  # node-opcua's own notices are plain text
                self.lines.put((time.monotonic(), json.loads(raw)))

    def next(self, event: str, timeout: float = 30.0) -> tuple[float, dict[str, Any]]:
        """The next line of that event (an error line fails the test)."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                at, line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                self.proc.kill()
                err = self.proc.stderr.read().decode() if self.proc.stderr else ""
                raise AssertionError(f"no {event!r} from the node client:\n{err[-2000:]}") from None
            if line["event"] == event:
                return at, line
            assert line["event"] != "error", line

    def wait(self) -> int:
        return self.proc.wait(timeout=60)


def _rotated_tool(api: Api) -> tuple[dict[str, Any], dict[str, Any]]:
    """A robot and its torch: v1 rotated 90 deg about z (KUKA A = 90), v2 another position;
    v1 active."""
    robot = api.robot("cell12-kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "torch", slot=3)
    s = math.sqrt(0.5)
    v1 = {
        "method": "manual",
        "tcp": {"position_mm": [1.5, -2.0, 150.0], "quaternion": [s, 0, 0, s]},
    }
    assert (
        api.post(f"/v1/tools/{tool['id']}/calibrations", v1, scope="calibrate").status_code == 201
    )
    api.manual(tool["id"], [0.0, 0.0, 151.25])
    back = api.post(f"/v1/tools/{tool['id']}/versions/1/activate", scope="calibrate")
    assert back.status_code == 200, back.text
    return robot, tool


@one_backend
def test_node_opcua_client_browses_reads_and_sees_an_activation_within_1s(
    api: Api, db: Database
) -> None:
    robot, tool = _rotated_tool(api)
    with publisher(db) as endpoint:
        client = NodeClient(
            "--endpoint", endpoint, "--user", "test-read", "--password", api.keys["read"],
            "--watch", "cell12-kr16/torch", "--until", "2", "--timeout-ms", "10000",
        )  # fmt: skip
        _, tree = client.next("tree")
        values = tree["robots"]["cell12-kr16"]["torch"]
        assert values["ActiveVersion"] == 1
        assert values["PositionMm"] == pytest.approx([1.5, -2.0, 150.0], abs=1e-9)
        assert values["Quaternion"] == pytest.approx([math.sqrt(0.5), 0, 0, math.sqrt(0.5)])
        assert values["KukaABC"] == pytest.approx([90.0, 0.0, 0.0], abs=1e-9)
        assert values["ControllerState"] == "none"
        served = api.get(f"/v1/tools/{tool['id']}").json()
        assert _instant(values["UpdatedAt"]) == pytest.approx(
            _instant(served["updated_at"]), abs=0.002
        )  # JavaScript dates hold milliseconds
        _, write = client.next("write")
        assert write["status"] in ("BadUserAccessDenied", "BadNotWritable")  # read-only

        _, subscribed = client.next("subscribed")
        assert subscribed["value"] == 1
        activated = api.post(f"/v1/tools/{tool['id']}/versions/2/activate", scope="calibrate")
        assert activated.status_code == 200, activated.text
        committed = time.monotonic()
        seen, changed = client.next("changed", timeout=10)
        assert changed["value"] == 2
        assert seen - committed < 1.0, f"the activation took {seen - committed:.3f} s to arrive"
        assert client.wait() == 0
    assert robot["name"] in tree["robots"]


def _instant(text: str) -> float:
    return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()


@one_backend
def test_a_wrong_password_and_anonymous_are_refused(api: Api, db: Database) -> None:
    api.robot("r1")
    with publisher(db) as endpoint:
        wrong = NodeClient("--endpoint", endpoint, "--user", "test-read", "--password", "nope")
        _, error = wrong.next("error")
        assert error["status"] == "BadUserAccessDenied"
        assert wrong.wait() == 3
        # the right key under another key's name, and no credentials at all: refused too
        assert asyncio.run(_sign_in(endpoint, "test-admin", api.keys["read"])) == "refused"
        assert asyncio.run(_sign_in(endpoint, None, None)) == "refused"
        assert asyncio.run(_sign_in(endpoint, "test-calibrate", api.keys["calibrate"])) == "in"
        # the password is never sent in clear: the None endpoint asks for it encrypted
        policies = asyncio.run(_user_name_policies(endpoint))
        assert policies["None"].endswith("#Basic256Sha256"), policies
        assert policies["SignAndEncrypt"].endswith("#None")  # the channel encrypts it


async def _user_name_policies(endpoint: str) -> dict[str, str]:
    """Security mode -> the SecurityPolicyUri the server sets for user name tokens."""
    found = {}
    for point in await Client(endpoint, timeout=10).connect_and_get_server_endpoints():
        for token in point.UserIdentityTokens:
            if token.TokenType == ua.UserTokenType.UserName:
                found[point.SecurityMode.name.rstrip("_")] = token.SecurityPolicyUri
    return found


async def _sign_in(endpoint: str, user: str | None, password: str | None) -> str:
    client = Client(endpoint, timeout=10)
    if user is not None and password is not None:
        client.set_user(user)
        client.set_password(password)
    try:
        await client.connect()
    except (UaStatusCodeError, UaError):
        return "refused"
    await client.disconnect()
    return "in"


@contextmanager
def opcua_client(
    endpoint: str, user: str | None = None, password: str | None = None
) -> Iterator[SyncClient]:
    """asyncua's client, connected (signed in with the key when given)."""
    client = SyncClient(endpoint, timeout=10)
    if user and password:
        client.set_user(user)
        client.set_password(password)
    client.connect()
    try:
        yield client
    finally:
        client.disconnect()


def _tree(client: SyncClient) -> dict[str, dict[str, dict[str, Any]]]:
    """Robots -> tools -> variable values, browsed now."""
    ns = client.get_namespace_index(NS)
    robots = client.nodes.objects.get_child(f"{ns}:Robots")
    tree: dict[str, dict[str, dict[str, Any]]] = {}
    for robot in robots.get_children():
        tools = robot.get_child(f"{ns}:Tools")
        tree[robot.read_browse_name().Name] = tool_values = {}
        for tool in tools.get_children():
            values: dict[str, Any] = {}
            for var in tool.get_children():
                values[var.read_browse_name().Name] = var.read_value()
            tool_values[tool.read_browse_name().Name] = values
    return tree


def _until(check: Any, timeout: float = 1.0) -> float:
    """Seconds until check() is true (fails after `timeout`)."""
    start = time.monotonic()
    while True:
        try:
            if check():
                return time.monotonic() - start
        except UaStatusCodeError:  # a node went away while being browsed: look again
            pass
        assert time.monotonic() - start < timeout, "not within the time allowed"
        time.sleep(0.05)


def test_robots_and_tools_appear_and_disappear_with_the_database(api: Api, db: Database) -> None:
    first = api.robot("r-first")
    with (
        publisher(db, TCPCAL_OPCUA_ANONYMOUS="true") as endpoint,
        opcua_client(endpoint) as client,  # anonymous allowed here
    ):
        assert _tree(client) == {"r-first": {}}

        second = api.robot("r-second")
        tool = api.tool(second["id"], "gripper", slot=1)
        _until(lambda: "gripper" in _tree(client).get("r-second", {}))
        values = _tree(client)["r-second"]["gripper"]
        assert values["ActiveVersion"] == 0  # no active version: 0 and empty arrays
        assert values["PositionMm"] == []

        api.manual(tool["id"], [0.0, 0.0, 99.5])
        _until(lambda: _tree(client)["r-second"]["gripper"]["ActiveVersion"] == 1)
        assert _tree(client)["r-second"]["gripper"]["PositionMm"] == [0, 0, 99.5]

        renamed = api.patch(f"/v1/robots/{second['id']}", {"name": "r-second-b"})
        assert renamed.status_code == 200, renamed.text
        _until(lambda: set(_tree(client)) == {"r-first", "r-second-b"})

        assert api.delete(f"/v1/tools/{tool['id']}").status_code == 204
        _until(lambda: _tree(client)["r-second-b"] == {})
        assert api.delete(f"/v1/robots/{first['id']}").status_code == 204
        _until(lambda: set(_tree(client)) == {"r-second-b"})


@one_backend
def test_clients_cannot_change_the_address_space(api: Api, db: Database) -> None:
    robot = api.robot("r1")
    tool = api.tool(robot["id"], "t1", slot=1)
    api.manual(tool["id"], [0.0, 0.0, 10.0])
    with publisher(db) as endpoint:
        assert asyncio.run(_try_changes(endpoint, api.keys["admin"])) == [
            "BadUserAccessDenied", "BadUserAccessDenied", "BadUserAccessDenied",
        ]  # fmt: skip
        with opcua_client(endpoint, "test-read", api.keys["read"]) as client:
            assert _tree(client)["r1"]["t1"]["ActiveVersion"] == 1


async def _try_changes(endpoint: str, key: str) -> list[str]:
    """Write a value, add a node, delete a node, as an admin key: each refusal's name."""
    refused = []
    client = Client(endpoint, timeout=10)
    client.set_user("test-admin")
    client.set_password(key)
    async with client:
        ns = await client.get_namespace_index(NS)
        robots = await client.nodes.objects.get_child(f"{ns}:Robots")
        tool = await (await robots.get_child(f"{ns}:r1")).get_child(f"{ns}:Tools")
        version = await tool.get_child([f"{ns}:t1", f"{ns}:ActiveVersion"])
        for attempt in (
            version.write_value(ua.Variant(5, ua.VariantType.Int32)),
            robots.add_folder(ns, "Intruder"),
            client.delete_nodes([version]),
        ):
            try:
                await attempt
                refused.append("accepted")
            except UaStatusCodeError as exc:
                refused.append(type(exc).__name__)
    return refused


def _run_publish(db: Database, **extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(TCPCAL), "publish"], cwd=REPO, env=_env(db, **extra),
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip


@one_backend
def test_a_port_in_use_or_a_bad_endpoint_stops_the_publisher_with_a_message(
    api: Api, db: Database
) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        busy = _run_publish(db, TCPCAL_OPCUA_ENDPOINT=f"opc.tcp://127.0.0.1:{port}/tcpcal/")
    assert busy.returncode == 2
    assert f"cannot listen on 127.0.0.1:{port}" in busy.stderr
    assert "TCPCAL_OPCUA_ENDPOINT" in busy.stderr
    for endpoint in ("http://127.0.0.1:4840/", "opc.tcp://h:99999/"):
        bad = _run_publish(db, TCPCAL_OPCUA_ENDPOINT=endpoint)
        assert bad.returncode == 2, bad.stderr
        assert f"TCPCAL_OPCUA_ENDPOINT={endpoint!r} is not usable" in bad.stderr
    half = _run_publish(
        db, TCPCAL_OPCUA_ENDPOINT="opc.tcp://127.0.0.1:4840/", TCPCAL_OPCUA_CERTIFICATE="c.der"
    )
    assert half.returncode == 2
    assert "set both TCPCAL_OPCUA_CERTIFICATE and TCPCAL_OPCUA_PRIVATE_KEY" in half.stderr


def _gauges(api: Api) -> dict[str, float]:
    text = api.get("/metrics").text
    return {
        s.name: s.value
        for family in text_string_to_metric_families(text)
        for s in family.samples
        if s.name.startswith(("tcpcal_outbox", "tcpcal_publisher"))
    }


def test_metrics_show_the_backlog_and_whether_a_publisher_runs(api: Api, db: Database) -> None:
    robot = api.robot("r1")
    api.tool(robot["id"], "t1", slot=1)
    time.sleep(0.3)
    before = _gauges(api)
    assert before["tcpcal_publisher_running"] == 0
    assert before["tcpcal_outbox_undelivered"] == 2  # robot.create, tool.create
    assert before["tcpcal_outbox_oldest_undelivered_age_seconds"] >= 0.3
    with publisher(db):
        _until(lambda: _gauges(api)["tcpcal_outbox_undelivered"] == 0, 5.0)
        during = _gauges(api)
        assert during["tcpcal_publisher_running"] == 1
        assert during["tcpcal_outbox_oldest_undelivered_age_seconds"] == 0
    _until(lambda: _gauges(api)["tcpcal_publisher_running"] == 0, 5.0)
