"""Controller faults through the API (issue 37): a deployment that stalls anywhere answers
within timeout_s + 1 s and leaves nothing the next deployment meets; refusals say what to do;
GET of a controller that is not set is 404 /no-controller."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from functools import partial
from typing import Any

import pytest

from app.services.controllers.failures import controller_problem
from app.vendors.connector import (
    ControllerProtocolError,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
)
from app.vendors.registry import SERVICE_PORTS
from tests.api.controller_rigs import Rig, rig
from tests.api.controller_rigs import secret_key as secret_key  # autouse: ABB passwords
from tests.conftest import Api
from tests.controllers.simbase import go_silent

TIMEOUT_S = 0.5
#: The attempt after a fault gets a timeout a loaded machine cannot miss: its subject is what
#: the failed session left behind (mastership, an RMI session), which a longer wait does not
#: clear (a held mastership or session is a refusal, not a timeout).
NEXT_TIMEOUT_S = 5.0
#: Where each simulator goes silent in a deployment, in its own names (simbase.Faults).
STAGES = [
    ("kuka_kvp", "read $TOOL_DATA[3]"),
    ("kuka_kvp", "write $TOOL_DATA[3]"),
    ("fanuc_rmi", "FRC_Connect"),
    ("fanuc_rmi", "FRC_WriteUToolData"),
    ("abb_rws1", "login"),
    ("abb_rws1", "POST /rw/rapid/symbol/data/RAPID/T_ROB1/user/tTorch"),
    ("abb_rws2", "login"),
    ("abb_rws2", "POST /rw/mastership/edit/request"),
    ("abb_rws2", "POST /rw/rapid/symbol/RAPID/T_ROB1/user/tTorch/data"),
    ("ur_rtde", "RTDE_CONTROL_PACKAGE_SETUP_OUTPUTS"),
    ("ur_rtde", "script"),
    ("techman", "TMSVR 12"),
    ("techman", "ChangeTCP"),
]


def _setup(api: Api, r: Rig, **controller: Any) -> tuple[str, str]:
    """A robot with the rig's controller and a calibrated tool in it: (robot id, tool id)."""
    robot = api.robot()
    body = r.controller_body(timeout_s=TIMEOUT_S, **controller)
    put = api.request("PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=body)
    assert put.status_code == 200, put.text
    tool = api.tool(robot["id"], **r.tool_fields)
    api.manual(tool["id"], [10.0, -5.0, 180.0])
    return robot["id"], tool["id"]


def _allow(api: Api, robot_id: str, r: Rig, timeout_s: float) -> None:
    """The robot's controller, as set up, with another timeout."""
    body = r.controller_body(timeout_s=timeout_s)
    put = api.request("PUT", f"/v1/robots/{robot_id}/controller", "admin", json=body)
    assert put.status_code == 200, put.text


def _deploy(api: Api, tool_id: str) -> Any:
    return api.post(f"/v1/tools/{tool_id}/deployments", {}, scope="calibrate")


def _settled(r: Rig) -> None:
    """The simulator has seen the failed session's connection close (FANUC serves one RMI
    session at a time and frees it when the connection closes; a Techman Listen node serves
    one client until it leaves)."""
    deadline = time.monotonic() + 2
    while _held(r) and time.monotonic() < deadline:
        time.sleep(0.01)


def _held(r: Rig) -> bool:
    if r.protocol == "techman":
        return bool(r.sim.listen_node_clients())
    return bool(getattr(r.sim, "session_open", False))


@pytest.mark.parametrize(("protocol", "stage"), STAGES)
def test_a_deploy_that_stalls_answers_within_the_timeout_and_the_next_one_succeeds(
    api: Api, protocol: str, stage: str
) -> None:
    with rig(protocol) as r:
        robot_id, tool_id = _setup(api, r)
        r.sim.fault = go_silent("before", stage)
        started = time.monotonic()
        failed = _deploy(api, tool_id)
        elapsed = time.monotonic() - started
        assert failed.status_code == 502, failed.text
        assert r.sim.stalled, f"the simulator never reached {stage}"
        assert elapsed < TIMEOUT_S + 1, elapsed
        r.sim.stalled = False  # the controller answers again
        _settled(r)
        assert not _held(r), "the failed session still holds the controller"
        _allow(api, robot_id, r, NEXT_TIMEOUT_S)
        done = _deploy(api, tool_id)
        assert done.status_code == 201, done.text
        assert done.json()["status"] == "verified"
        r.assert_holds([10.0, -5.0, 180.0], [1.0, 0.0, 0.0, 0.0])
        if protocol.startswith("abb"):
            assert r.sim.mastership_holder is None


def test_a_fanuc_session_dropped_mid_deploy_leaves_nothing_the_next_deploy_meets(
    api: Api,
) -> None:
    """The controller closes the session's connection when the write arrives (a dropped
    session). Before, every session ran FRC_Initialize, and the dropped one left RMI_MOVE
    holding program control: the next deploy got 'MEMO-015 Program already exists'."""
    with rig("fanuc_rmi") as r:
        robot_id, tool_id = _setup(api, r)
        r.sim.drop_at = "FRC_WriteUToolData"
        dropped = _deploy(api, tool_id)
        assert dropped.status_code == 502, dropped.text
        assert dropped.json()["type"].endswith("/controller-unreachable")
        r.sim.drop_at = None
        _settled(r)
        _allow(api, robot_id, r, NEXT_TIMEOUT_S)
        done = _deploy(api, tool_id)
        assert done.status_code == 201, done.text
        assert not r.sim.rmi_move_held


def test_a_fanuc_controller_another_client_holds_says_what_to_do(api: Api) -> None:
    with rig("fanuc_rmi") as r:
        robot_id, tool_id = _setup(api, r)
        r.sim.session_open = True  # another RMI client's session
        refused = _deploy(api, tool_id)
        assert refused.status_code == 502, refused.text
        problem = refused.json()
        assert "RMIT-026 Robot is Already Connected" in problem["controller_message"]
        assert "one client at a time" in problem["detail"]
        recon = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read").json()
        assert "one client at a time" in recon["tools"][0]["error"]


@pytest.mark.parametrize("protocol", ["abb_rws1", "abb_rws2"])
def test_a_401_names_the_user_and_where_to_set_user_and_password(api: Api, protocol: str) -> None:
    with rig(protocol) as r:
        robot_id, tool_id = _setup(api, r, username="Operator", password="wrong-password-x1")
        refused = _deploy(api, tool_id)
        assert refused.status_code == 502, refused.text
        problem = refused.json()
        assert problem["type"].endswith("/controller-refused")
        assert "401" in problem["controller_message"]
        detail = problem["detail"]
        assert problem["controller_message"] in detail
        assert "'Operator'" in detail
        assert f"PUT /v1/robots/{robot_id}/controller" in detail
        assert "`username`" in detail
        assert "`password`" in detail
        assert "wrong-password-x1" not in refused.text
        recon = api.post(f"/v1/robots/{robot_id}/reconcile", scope="read").json()
        assert f"PUT /v1/robots/{robot_id}/controller" in recon["tools"][0]["error"]


def test_abb_rws2_on_a_port_that_answers_plain_http_says_it_is_not_tls(api: Api) -> None:
    with rig("abb_rws1") as r:  # RobotWare 6: plain HTTP
        _, tool_id = _setup(api, r, protocol="abb_rws2")
        failed = _deploy(api, tool_id)
        assert failed.status_code == 502, failed.text
        detail = failed.json()["detail"]
        assert "plain HTTP, not TLS" in detail
        assert "abb_rws1" in detail
        assert "certificate" not in detail  # not the advice for an untrusted certificate


def test_a_kuka_variable_the_krc_does_not_have_is_named_as_such(api: Api) -> None:
    with rig("kuka_kvp") as r:
        _, tool_id = _setup(api, r)
        r.sim.undeclared.add("$TOOL_DATA[3]")
        refused = _deploy(api, tool_id)
        assert refused.status_code == 502, refused.text
        detail = refused.json()["detail"]
        assert "the KRC has no variable $TOOL_DATA[3]" in detail
        assert "slot" in detail


def test_get_of_a_controller_not_set_is_404_no_controller(api: Api) -> None:
    robot = api.robot()
    got = api.get(f"/v1/robots/{robot['id']}/controller")
    assert got.status_code == 404, got.text
    assert got.json()["type"].endswith("/no-controller")
    assert f"PUT /v1/robots/{robot['id']}/controller" in got.json()["detail"]
    # What needs a controller still answers 409 /no-controller (a conflict with the state).
    tool = api.tool(robot["id"], slot=1)
    api.manual(tool["id"], [0, 0, 100])
    deploy = _deploy(api, tool["id"])
    assert deploy.status_code == 409
    assert deploy.json()["type"].endswith("/no-controller")


def test_a_techman_robot_says_what_to_do_and_no_answer_holds_a_secret(
    api: Api, caplog: pytest.LogCaptureFixture
) -> None:
    """A project not waiting in its Listen node refuses the script ($CPERR F1): nothing was
    written, and the answer says to let the flow reach the node; no project running refuses
    the connection: the answer says to start one. A password stored for the controller (a
    Listen node and an Ethernet Slave take none) is in no answer, audit event or log line."""
    secret = "tm-Pa55-not-to-be-seen-1c9e"
    with rig("techman") as r:
        caplog.set_level("DEBUG")
        robot_id, tool_id = _setup(api, r, password=secret)
        texts = [api.get(f"/v1/robots/{robot_id}/controller").text]
        r.sim.leave_listen_node()
        refused = _deploy(api, tool_id)
        assert refused.status_code == 502, refused.text
        problem = refused.json()
        assert problem["type"].endswith("/controller-refused")
        assert problem["deployment_status"] == "not_written"
        assert "$CPERR F1" in problem["controller_message"]
        assert "reach its Listen node" in problem["detail"]
        r.sim.stop_project()
        stopped = _deploy(api, tool_id)
        assert stopped.status_code == 502, stopped.text
        assert stopped.json()["deployment_status"] == "not_written"
        assert "no project is running" in stopped.json()["detail"]
        assert "Play" in stopped.json()["detail"]
        r.sim.start_project()
        done = _deploy(api, tool_id)
        assert done.status_code == 201, done.text
        assert done.json()["scope"] == "live"
        texts += [refused.text, stopped.text, done.text]
        texts.append(api.post(f"/v1/robots/{robot_id}/reconcile", scope="read").text)
        texts.append(api.get(f"/v1/robots/{robot_id}/controller/pose", scope="calibrate").text)
        texts.append(api.get(f"/v1/tools/{tool_id}/deployments").text)
        texts.append(api.get("/v1/audit", params={"robot_id": robot_id}, scope="admin").text)
        texts.append(caplog.text)
    assert all(secret not in t for t in texts)


def test_a_connectors_failure_is_worded_as_a_capture_and_a_deployment_say_it() -> None:
    """One function words the 502 for both; the refusal's words differ on purpose (a
    capture gives the connector's sentence, a deployment the controller's words and remedy,
    then its status words), the rest only in what the attempt left."""
    settings = ControllerSettings(
        protocol="kuka_kvp", host="127.0.0.1", port=7000, username=None, password=None
    )
    refused = ControllerRefused("the KRC refused X", controller_message="$X", remedy="do Y")
    capture = partial(controller_problem, robot_id="r1", left="nothing was kept")
    deploy = partial(controller_problem, robot_id="r1", left="LEFT", refusal="remedy")
    got = capture(refused, settings, refusal="connector")
    assert got.detail == "the controller refused ($X): the KRC refused X; do Y; nothing was kept"
    assert got.members == {"controller_message": "$X"}
    got = deploy(refused, settings, members={"deployment_status": "not_written"})
    assert got.detail == "the controller refused: $X; do Y; LEFT"
    assert got.members == {"deployment_status": "not_written", "controller_message": "$X"}
    gone = ControllerUnreachable("timed out")
    assert capture(gone, settings, refusal="connector").detail == (
        "the controller at 127.0.0.1:7000 could not be reached within 5 s: timed out; "
        "nothing was kept"
    )
    assert deploy(gone, settings, sent=True).detail == (
        "the controller at 127.0.0.1:7000 stopped answering after the write was sent: "
        "timed out; LEFT"
    )
    garbled = deploy(ControllerProtocolError("garbage"), settings)
    assert garbled.detail == (
        "the controller at 127.0.0.1:7000 answered something that is not its protocol: "
        "garbage; LEFT"
    )
    assert garbled.kind == "controller-unreachable"


@contextmanager
def _silent_listener() -> Iterator[int]:
    """A port that accepts every TCP connection and never sends a byte (another maker's
    controller, or another service's port, met with the wrong protocol): its port."""
    server = socket.create_server(("127.0.0.1", 0))
    held: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        server.settimeout(0.05)
        while not stop.is_set():
            with suppress(TimeoutError):
                held.append(server.accept()[0])

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield server.getsockname()[1]
    finally:
        stop.set()
        thread.join()
        for conn in held:
            conn.close()
        server.close()


@pytest.mark.parametrize("protocol", ["kuka_kvp", "fanuc_rmi", "abb_rws1", "ur_rtde", "techman"])
def test_a_port_that_accepts_and_never_answers_is_named_as_such(api: Api, protocol: str) -> None:
    """Issue 51 #8: a controller that accepted the connection and never answered said
    'could not be reached within 3 s', sending a person to check the cable and the address
    when something did answer the port: the protocol or the port is what to check."""
    robot = api.robot()
    with _silent_listener() as port:
        body: dict[str, Any] = {"protocol": protocol, "host": "127.0.0.1", "timeout_s": 0.5}
        services = SERVICE_PORTS.get(protocol)
        if services:
            body["ports"] = dict.fromkeys(services, port)
        else:
            body["port"] = port
        put = api.request("PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=body)
        assert put.status_code == 200, put.text
        read = api.get(f"/v1/robots/{robot['id']}/controller/pose", scope="calibrate")
    assert read.status_code == 502, read.text
    detail = read.json()["detail"]
    assert "could not be reached" not in detail, detail
    assert f"127.0.0.1:{port} accepted the TCP connection and sent nothing within 0.5 s" in detail
    assert "Something answered the port (the TCP connection was accepted)" in detail
    assert f"check that the robot's controller speaks {protocol} and that the port is its" in (
        detail
    )
    # the fix said both ways: the HTTP call and the CLI's command (printed by tcpcal deploy)
    assert "set the protocol and port with PUT /v1/robots/" in detail
    assert "or tcpcal connect ROBOT --protocol P --port N)" in detail
    assert detail.endswith("nothing was kept"), detail


def test_a_port_that_refuses_the_connection_is_still_not_reached(api: Api) -> None:
    """The other side of it: nothing listening is 'could not be reached', no protocol hint."""
    robot = api.robot()
    with socket.create_server(("127.0.0.1", 0)) as closed:
        port = closed.getsockname()[1]
    body = {"protocol": "kuka_kvp", "host": "127.0.0.1", "port": port, "timeout_s": 0.5}
    api.request("PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=body)
    read = api.get(f"/v1/robots/{robot['id']}/controller/pose", scope="calibrate")
    assert read.status_code == 502, read.text
    detail = read.json()["detail"]
    assert f"could not be reached within 0.5 s: cannot connect to 127.0.0.1:{port}" in detail
    assert "accepted" not in detail
