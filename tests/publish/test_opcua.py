"""The publisher's OPC UA server, as plant clients see it.

`tcpcal publish` runs as its own process with TCPCAL_OPCUA_ENDPOINT on a free loopback port;
the changes are made through the API (in-process) on the same database. Every value these
tests check is read by node-opcua (another implementation than the server's asyncua: issue
42), run by Node from tests/opcua_client (`npm ci` there; `make test` does it): one client
process per session, answering the commands the test writes to it (tests/opcua_client/
client.js says which).
"""

from __future__ import annotations

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
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest
from prometheus_client.parser import text_string_to_metric_families

from tests.api.frame_versions import add_frame_version
from tests.conftest import Api, Database, one_backend
from tests.publish.plant_changes import force, out_of_tolerance_version, rollback

REPO = Path(__file__).resolve().parents[2]
NODE_CLIENT = REPO / "tests" / "opcua_client"
TCPCAL = Path(sys.executable).parent / "tcpcal"

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


class Served(str):
    """The endpoint, and how long the publisher took to exit after SIGTERM (once it did)."""

    stopped_in: float | None = None


@contextmanager
def publisher(db: Database, **extra: str) -> Iterator[Served]:
    """`tcpcal publish` serving OPC UA on a free port; yields the endpoint once it listens,
    and records on it how long SIGTERM took to stop the publisher."""
    port = _free_port()
    endpoint = Served(f"opc.tcp://127.0.0.1:{port}/tcpcal/")
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
        signalled = time.monotonic()
        try:
            proc.wait(timeout=10)
            endpoint.stopped_in = time.monotonic() - signalled
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


Line = dict[str, Any]


class NodeClient:
    """The node-opcua client (tests/opcua_client/client.js) in a process of its own: commands
    written to its stdin, its JSON lines read as they come with the time each came."""

    def __init__(self, endpoint: str, user: str | None = None, password: str | None = None,
                 *flags: str) -> None:  # fmt: skip
        sign_in = [] if user is None else ["--user", user, "--password", password or ""]
        self.proc = subprocess.Popen(
            [_node(), str(NODE_CLIENT / "client.js"), "--endpoint", endpoint, *sign_in, *flags],
            cwd=NODE_CLIENT,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.lines: queue.Queue[tuple[float, Line]] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for raw in self.proc.stdout:
            if raw.startswith(b"{"):  # node-opcua's own notices are plain text
                self.lines.put((time.monotonic(), json.loads(raw)))

    def send(self, op: str, **fields: Any) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps({"op": op, **fields}).encode() + b"\n")
        self.proc.stdin.flush()

    def answer(self, *events: str, timeout: float = 30.0) -> tuple[float, Line]:
        """The next line of one of these events, or an error line."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                at, line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                self.proc.kill()
                err = self.proc.stderr.read().decode() if self.proc.stderr else ""
                raise AssertionError(f"no {events} from the node client:\n{err[-2000:]}") from None
            if line["event"] in (*events, "error"):
                return at, line

    def next(self, event: str, timeout: float = 30.0) -> tuple[float, Line]:
        """The next line of that event (an error line fails the test)."""
        at, line = self.answer(event, timeout=timeout)
        assert line["event"] == event, line
        return at, line

    def tree(self, *, details: bool = False, folder: str = "Tools") -> Line:
        """Robots -> tools (or another folder's items: "Frames") -> variable values as
        node-opcua reads them now (with `details`, also each variable's attributes and
        engineering units under "variables")."""
        self.send("tree", details=details, folder=folder)
        return self.next("tree")[1]

    def values(self, folder: str = "Tools") -> dict[str, dict[str, dict[str, Any]]] | None:
        """The tree's values now; None when a node went away while it was read."""
        self.send("tree", folder=folder)
        _, line = self.answer("tree")
        return line["robots"] if line["event"] == "tree" else None

    def close(self) -> int:
        """Close stdin (the client ends its session and exits); its exit code."""
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        return self.proc.wait(timeout=60)


@contextmanager
def node_client(endpoint: str, user: str | None = None, password: str | None = None
                ) -> Iterator[NodeClient]:  # fmt: skip
    """A signed-in node-opcua client (anonymous without a user)."""
    client = NodeClient(endpoint, user, password)
    try:
        client.next("session")
        yield client
    finally:
        if client.proc.poll() is None:
            assert client.close() == 0


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
    with publisher(db) as endpoint, node_client(endpoint, "test-read", api.keys["read"]) as client:
        tree = client.tree()
        values = tree["robots"]["cell12-kr16"]["torch"]
        assert values["ActiveVersion"] == 1
        assert values["PositionMm"] == pytest.approx([1.5, -2.0, 150.0], abs=1e-9)
        assert values["Quaternion"] == pytest.approx([math.sqrt(0.5), 0, 0, math.sqrt(0.5)])
        assert values["KukaABC"] == pytest.approx([90.0, 0.0, 0.0], abs=1e-9)
        assert values["ControllerState"] == "none"
        assert (values["Status"], values["ActivationKind"]) == ("accepted", "explicit")
        assert values["ActivationReason"] == ""
        served = api.get(f"/v1/tools/{tool['id']}").json()
        assert _instant(values["UpdatedAt"]) == pytest.approx(
            _instant(served["updated_at"]), abs=0.002
        )  # JavaScript dates hold milliseconds
        client.send("write", path="cell12-kr16/torch/ActiveVersion", value=99)
        _, write = client.next("write")
        assert write["status"] in ("BadUserAccessDenied", "BadNotWritable")  # read-only

        client.send("watch", path="cell12-kr16/torch/ActiveVersion", until=2, timeout_ms=10000)
        _, subscribed = client.next("subscribed")
        assert subscribed["value"] == 1
        activated = api.post(f"/v1/tools/{tool['id']}/versions/2/activate", scope="calibrate")
        assert activated.status_code == 200, activated.text
        committed = time.monotonic()
        seen, changed = client.next("changed", timeout=10)
        assert changed["value"] == 2
        assert seen - committed < 1.0, f"the activation took {seen - committed:.3f} s to arrive"
    assert robot["name"] in tree["robots"]


def _instant(text: str) -> float:
    return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()


#: OPC UA Part 8 5.6.3 and the UNECE codes (Recommendation 20): millimetre MMT, degree DD;
#: UnitId is the code's characters as one integer ("MMT": 0x4D 0x4D 0x54).
UNECE = "http://www.opcfoundation.org/UA/units/un/cefact"
MMT, DD = 5066068, 17476
BASE_ANALOG_TYPE = "ns=0;i=15318"


@one_backend
def test_a_forced_out_of_tolerance_version_shows_its_status_kind_and_reason(
    api: Api, db: Database
) -> None:
    """Issue 37: a cell reading the node must tell it runs an out-of-tolerance TCP, why, and
    when it is back on an accepted one."""
    robot = api.robot("cell7-kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "torch", slot=1)
    api.manual(tool["id"], [0.0, 0.0, 150.0])
    bad = out_of_tolerance_version(api, tool["id"])
    with publisher(db) as endpoint, node_client(endpoint, "test-read", api.keys["read"]) as client:
        values = client.tree()["robots"]["cell7-kr16"]["torch"]
        assert (values["ActiveVersion"], values["Status"]) == (1, "accepted")
        assert (values["ActivationKind"], values["ActivationReason"]) == ("calibration:auto", "")

        force(api, tool["id"], bad, "probe bent, interim TCP until the new one is calibrated")
        _until(lambda: _torch(client, "cell7-kr16")["ActiveVersion"] == bad, 1.0)
        values = _torch(client, "cell7-kr16")
        assert values["Status"] == "out_of_tolerance"
        assert values["ActivationKind"] == "forced"
        assert values["ActivationReason"] == (
            "probe bent, interim TCP until the new one is calibrated"
        )

        rollback(api, tool["id"])
        _until(lambda: _torch(client, "cell7-kr16")["ActiveVersion"] == 1, 1.0)
        values = _torch(client, "cell7-kr16")
        assert (values["Status"], values["ActivationKind"]) == ("accepted", "rollback")
        assert values["ActivationReason"] == ""


def _torch(client: NodeClient, robot: str) -> dict[str, Any]:
    tree = client.values()
    return {} if tree is None else tree[robot].get("torch", {})


@one_backend
def test_every_variable_has_a_description_and_lengths_and_angles_their_units(
    api: Api, db: Database
) -> None:
    robot = api.robot("r1")
    tool = api.tool(robot["id"], "t1", slot=1)
    api.manual(tool["id"], [0.0, 0.0, 10.0])
    with publisher(db) as endpoint, node_client(endpoint, "test-read", api.keys["read"]) as client:
        variables = client.tree(details=True)["variables"]
    names = {path.rsplit("/", 1)[1] for path in variables}
    assert names == {
        "ActiveVersion", "PositionMm", "Quaternion", "KukaABC", "Status", "ActivationKind",
        "ActivationReason", "ControllerState", "UpdatedAt",
    }  # fmt: skip
    for path, attrs in variables.items():
        name = path.rsplit("/", 1)[1]
        description = attrs["description"]["text"]
        assert description != name, (path, description)  # a real one, not the browse name
        assert len(description.split()) >= 5, (path, description)
        assert attrs["userAccessLevel"] & 0b10 == 0, path  # CurrentWrite not granted
    position = variables["r1/t1/PositionMm"]
    assert position["engineeringUnits"] == {
        "namespaceUri": UNECE,
        "unitId": MMT,
        "displayName": {"text": "mm", "locale": "en"},
        "description": {"text": "millimetre", "locale": "en"},
        "propertyNamespace": 0,  # Part 8's EngineeringUnits, a standard browse name
    }
    assert (position["valueRank"], position["arrayDimensions"]) == (1, [3])
    assert position["typeDefinition"] == BASE_ANALOG_TYPE
    abc = variables["r1/t1/KukaABC"]
    assert (abc["engineeringUnits"]["namespaceUri"], abc["engineeringUnits"]["unitId"]) == (
        UNECE,
        DD,
    )
    assert abc["engineeringUnits"]["description"]["text"].startswith("degree")
    assert abc["typeDefinition"] == BASE_ANALOG_TYPE
    assert "degree" in abc["engineeringUnitsDescription"]["text"]
    for unitless in ("ActiveVersion", "Quaternion", "Status", "ControllerState", "UpdatedAt"):
        assert variables[f"r1/t1/{unitless}"]["engineeringUnits"] is None, unitless


@one_backend
def test_a_wrong_password_and_anonymous_are_refused(api: Api, db: Database) -> None:
    api.robot("r1")
    with publisher(db) as endpoint:
        assert _sign_in(endpoint, "test-read", "nope") == "BadUserAccessDenied"
        # the right key under another key's name, and no credentials at all: refused too
        assert _sign_in(endpoint, "test-admin", api.keys["read"]) == "BadUserAccessDenied"
        assert _sign_in(endpoint, None, None) != "in"  # (node-opcua finds no anonymous policy)
        assert _sign_in(endpoint, "test-calibrate", api.keys["calibrate"]) == "in"
        # the password is never sent in clear: the None endpoint asks for it encrypted
        policies = _user_name_policies(endpoint)
        assert policies["None"].endswith("#Basic256Sha256"), policies
        assert policies["SignAndEncrypt"].endswith("#None")  # the channel encrypts it


def _sign_in(endpoint: str, user: str | None, password: str | None) -> str:
    """ "in", or the status a refused sign-in got (the client then exits 3)."""
    client = NodeClient(endpoint, user, password)
    _, line = client.answer("session")
    if line["event"] == "session":
        assert client.close() == 0
        return "in"
    assert line["op"] == "sign-in", line
    assert client.proc.wait(timeout=30) == 3
    return str(line["status"])


def _user_name_policies(endpoint: str) -> dict[str, str]:
    """Security mode -> the SecurityPolicyUri the server sets for user name tokens."""
    client = NodeClient(endpoint, None, None, "--endpoints")
    _, line = client.next("endpoints")
    assert client.proc.wait(timeout=30) == 0
    found = {}
    for point in line["points"]:
        for token in point["tokens"]:
            if token["type"] == "UserName":
                found[point["mode"]] = token["policy"]
    return found


def _until(check: Callable[[], bool], timeout: float = 1.0) -> float:
    """Seconds until check() is true (fails after `timeout`)."""
    start = time.monotonic()
    while not check():
        assert time.monotonic() - start < timeout, "not within the time allowed"
        time.sleep(0.05)
    return time.monotonic() - start


def test_robots_and_tools_appear_and_disappear_with_the_database(api: Api, db: Database) -> None:
    first = api.robot("r-first")
    with (
        publisher(db, TCPCAL_OPCUA_ANONYMOUS="true") as endpoint,
        node_client(endpoint) as client,  # anonymous allowed here
    ):
        tree = client.values

        assert tree() == {"r-first": {}}

        second = api.robot("r-second")
        tool = api.tool(second["id"], "gripper", slot=1)
        _until(lambda: "gripper" in (tree() or {}).get("r-second", {}))
        values = (tree() or {})["r-second"]["gripper"]
        assert values["ActiveVersion"] == 0  # no active version: 0, empty arrays and strings
        assert values["PositionMm"] == []
        assert (values["Status"], values["ActivationKind"]) == ("", "")

        api.manual(tool["id"], [0.0, 0.0, 99.5])
        _until(lambda: (tree() or {})["r-second"]["gripper"]["ActiveVersion"] == 1)
        assert (tree() or {})["r-second"]["gripper"]["PositionMm"] == [0, 0, 99.5]

        # A rename or an archive rebuilds or drops a subtree, seen within the second
        # docs/publishing.md promises for the values (the server's side alone is held by
        # test_opcua_parts.py: 2.3 s for a robot of ten tools before deletes stopped scanning
        # the whole address space; 2 s here hid it).
        renamed = api.patch(f"/v1/robots/{second['id']}", {"name": "r-second-b"})
        assert renamed.status_code == 200, renamed.text
        _until(lambda: set(tree() or {}) == {"r-first", "r-second-b"})

        assert api.delete(f"/v1/tools/{tool['id']}").status_code == 204
        _until(lambda: (tree() or {}).get("r-second-b") == {})
        assert api.delete(f"/v1/robots/{first['id']}").status_code == 204
        _until(lambda: set(tree() or {}) == {"r-second-b"})


def test_frames_are_shown_beside_the_tools_with_the_same_variables_and_units(
    api: Api, db: Database
) -> None:
    """Contract v1.4: Objects/Robots/<robot>/Frames/<frame>/ with the tools' variables and
    EngineeringUnits, following the database as the tools' do."""
    robot = api.robot("kr16-f", vendor="KUKA")
    made = api.post(
        f"/v1/robots/{robot['id']}/frames", {"name": "fixture-a", "kind": "base", "slot": 2}
    )
    assert made.status_code == 201, made.text
    frame = made.json()
    assert add_frame_version(frame["id"], [500.0, 10.0, 0.0]) == 1
    assert api.post(f"/v1/frames/{frame['id']}/versions/1/activate", scope="calibrate").is_success
    with publisher(db) as endpoint, node_client(endpoint, "test-read", api.keys["read"]) as client:
        tree = client.tree(details=True, folder="Frames")
        values = tree["robots"]["kr16-f"]["fixture-a"]
        assert values["ActiveVersion"] == 1
        assert values["PositionMm"] == pytest.approx([500.0, 10.0, 0.0])
        assert values["Quaternion"] == pytest.approx([1.0, 0.0, 0.0, 0.0])
        assert values["KukaABC"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
        assert (values["Status"], values["ActivationKind"]) == ("accepted", "explicit")
        assert values["ControllerState"] == "none"
        assert client.tree()["robots"]["kr16-f"] == {}  # its Tools folder, empty
        variables = tree["variables"]
        position = variables["kr16-f/fixture-a/PositionMm"]
        assert position["description"]["text"].startswith(
            "The active pose's position x, y, z in the robot's base frame"
        )
        assert (position["engineeringUnits"]["unitId"], position["typeDefinition"]) == (
            MMT,
            BASE_ANALOG_TYPE,
        )
        assert variables["kr16-f/fixture-a/KukaABC"]["engineeringUnits"]["unitId"] == DD
        assert (
            "frame's active pose version"
            in (variables["kr16-f/fixture-a/ActiveVersion"]["description"]["text"])
        )

        def fixture() -> dict[str, Any]:
            return ((client.values("Frames") or {}).get("kr16-f") or {}).get("fixture-a", {})

        assert add_frame_version(frame["id"], [502.0, 10.0, 0.0]) == 2
        activated = api.post(f"/v1/frames/{frame['id']}/versions/2/activate", scope="calibrate")
        assert activated.is_success, activated.text
        _until(lambda: fixture().get("ActiveVersion") == 2)
        assert fixture()["PositionMm"] == pytest.approx([502.0, 10.0, 0.0])
        assert api.delete(f"/v1/frames/{frame['id']}").status_code == 204
        _until(lambda: (client.values("Frames") or {}).get("kr16-f") == {})


@one_backend
def test_clients_cannot_change_the_address_space(api: Api, db: Database) -> None:
    robot = api.robot("r1")
    tool = api.tool(robot["id"], "t1", slot=1)
    api.manual(tool["id"], [0.0, 0.0, 10.0])
    with publisher(db) as endpoint:
        with node_client(endpoint, "test-admin", api.keys["admin"]) as admin:
            for op, fields in (
                ("write", {"path": "r1/t1/ActiveVersion", "value": 5}),
                ("add", {}),
                ("delete", {"path": "r1/t1/ActiveVersion"}),
            ):
                admin.send(op, **fields)
                assert admin.next(op)[1]["status"] == "BadUserAccessDenied", op
        with node_client(endpoint, "test-read", api.keys["read"]) as client:
            assert set(client.tree()["robots"]) == {"r1"}  # nothing added
            values = client.tree()["robots"]["r1"]["t1"]
            assert values["ActiveVersion"] == 1  # nothing written, nothing deleted
            assert values["PositionMm"] == [0, 0, 10]
            watching = NodeClient(endpoint, "test-read", api.keys["read"])
            watching.next("session")  # still signed in when the publisher stops
    assert endpoint.stopped_in is not None
    assert endpoint.stopped_in < 1.0, f"SIGTERM took {endpoint.stopped_in:.2f} s"
    watching.proc.kill()


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
