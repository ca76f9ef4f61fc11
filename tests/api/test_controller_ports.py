"""Protocols of several services take `ports` in place of `port` (contract v1.3, "More
controllers"): techman {listen_node, ethernet_slave}, yaskawa_hses {robot, file}, ur_rtde
{rtde, secondary}, each defaulting to the real one; the answers show the ports in use, the
row keeps them, a backup carries them, and a port given the wrong way is a 422 naming the
field and what to send instead, with nothing stored."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import create_engine, text

from app.storage.backup import backup, restore
from app.storage.migrate import upgrade
from app.vendors.connector import ControllerSettings
from app.vendors.registry import port_of, ports_in_use, where
from testbed.databases import fresh_database
from tests.conftest import PG_URL, Api, Database

#: The real ports of each protocol's services (the vendors' defaults, contract v1.3).
REAL_PORTS: dict[str, dict[str, int]] = {
    "techman": {"listen_node": 5890, "ethernet_slave": 5891},
    "yaskawa_hses": {"robot": 10040, "file": 10041},
    "ur_rtde": {"rtde": 30004, "secondary": 30002},
}


def _put(api: Api, robot_id: str, **body: Any) -> Any:
    return api.request("PUT", f"/v1/robots/{robot_id}/controller", "admin", json=body)


def _stored(url: str, robot_id: str) -> Any:
    engine = create_engine(url)
    try:
        with engine.connect() as conn:
            return conn.execute(
                text("SELECT port, ports FROM robot_controllers WHERE robot_id = :r"),
                {"r": robot_id},
            ).one_or_none()
    finally:
        engine.dispose()


def _ports(value: object) -> object:
    """A JSON column as read by a plain SELECT: a dict (PostgreSQL) or its text (SQLite)."""
    import json

    return json.loads(value) if isinstance(value, str) else value


@pytest.mark.parametrize("protocol", list(REAL_PORTS))
def test_each_service_defaults_to_its_real_port_and_the_answers_show_them(
    api: Api, db: Database, protocol: str
) -> None:
    robot = api.robot()
    r = _put(api, robot["id"], protocol=protocol, host="10.0.0.7")
    assert r.status_code == 200, r.text
    assert r.json()["ports"] == REAL_PORTS[protocol]
    assert r.json()["port"] is None
    got = api.get(f"/v1/robots/{robot['id']}/controller").json()
    assert (got["port"], got["ports"]) == (None, REAL_PORTS[protocol])
    stored = _stored(db.url, robot["id"])
    assert stored.port is None
    assert _ports(stored.ports) == REAL_PORTS[protocol]


def test_ports_given_are_used_and_those_left_out_keep_their_default(
    api: Api, db: Database, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A plant (or a test's simulator) on other ports: each service where it was told,
    the one not named on its real port; what a connector is given says the same."""
    from app.services.robots.connection import get_controller, settings_of
    from app.storage.db import session_scope

    robot = api.robot()
    r = _put(api, robot["id"], protocol="ur_rtde", host="127.0.0.1", ports={"rtde": 40004})
    assert r.status_code == 200, r.text
    assert r.json()["ports"] == {"rtde": 40004, "secondary": 30002}
    audit = api.get(f"/v1/audit?robot_id={robot['id']}&action=controller.set", scope="admin")
    assert audit.json()["items"][0]["detail"]["ports"] == {"rtde": 40004, "secondary": 30002}
    r = _put(api, robot["id"], protocol="techman", host="127.0.0.1", ports={"ethernet_slave": 6001})
    assert r.json()["ports"] == {"listen_node": 5890, "ethernet_slave": 6001}
    # What a connector is given, once its protocol has one.
    monkeypatch.setattr("app.services.robots.connection.has_connector", lambda protocol: True)
    with session_scope(write=False) as session:
        settings = settings_of(get_controller(session, robot["id"]))
    assert port_of(settings, "listen_node") == 5890
    assert port_of(settings, "ethernet_slave") == 6001
    assert ports_in_use(settings) == {"listen_node": 5890, "ethernet_slave": 6001}
    assert settings.port == 5890  # the main service's
    assert where(settings) == "127.0.0.1 (listen_node 5890, ethernet_slave 6001)"
    with pytest.raises(ValueError, match="its services: listen_node, ethernet_slave"):
        port_of(settings, "rtde")
    # Back to a single-service protocol: its port, and no ports.
    r = _put(api, robot["id"], protocol="kuka_kvp", host="127.0.0.1")
    assert (r.json()["port"], r.json()["ports"]) == (7000, None)
    assert _ports(_stored(db.url, robot["id"]).ports) is None


def test_settings_of_a_protocol_of_several_services_default_each_port() -> None:
    """Built without `ports` (as a test may), each service is on its real one."""
    settings = ControllerSettings("yaskawa_hses", "127.0.0.1", 10040, None, None)
    assert ports_in_use(settings) == REAL_PORTS["yaskawa_hses"]
    single = ControllerSettings("kuka_kvp", "127.0.0.1", 7000, None, None)
    assert ports_in_use(single) == {}
    assert where(single) == "127.0.0.1:7000"
    with pytest.raises(ValueError, match="it has one port, `port`"):
        port_of(single, "robot")
    assert hash(settings) == hash(
        ControllerSettings("yaskawa_hses", "127.0.0.1", 10040, None, None)
    )


@pytest.mark.parametrize(
    ("body", "loc", "words"),
    [
        # `port` for a protocol of several services: say to send `ports`, with the services
        (
            {"protocol": "techman", "port": 5890},
            ["body", "port"],
            ["`ports`", "listen_node (default 5890)", "ethernet_slave (default 5891)"],
        ),
        ({"protocol": "ur_rtde", "port": 30004}, ["body", "port"], ["`ports`", "rtde"]),
        # `ports` for a single-service protocol: say to send `port`
        (
            {"protocol": "kuka_kvp", "ports": {"listen_node": 7000}},
            ["body", "ports"],
            ["`port` (default 7000)", "not `ports`"],
        ),
        ({"protocol": "abb_rws2", "ports": {}}, ["body", "ports"], ["`port` (default 443)"]),
        # a service the protocol does not have: name its services
        (
            {"protocol": "yaskawa_hses", "ports": {"rtde": 30004}},
            ["body", "ports", "rtde"],
            ["no service 'rtde'", "robot (default 10040)", "file (default 10041)"],
        ),
    ],
)
def test_a_port_given_the_wrong_way_is_422_naming_the_field_and_stores_nothing(
    api: Api, db: Database, body: dict[str, Any], loc: list[str], words: list[str]
) -> None:
    robot = api.robot()
    r = _put(api, robot["id"], host="10.0.0.7", **body)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    assert r.json()["errors"][0]["loc"] == loc
    for said in words:
        assert said in r.json()["detail"]
    assert _stored(db.url, robot["id"]) is None


@pytest.mark.parametrize("value", [0, 65536, "5890", 5890.5, None, True])
def test_a_service_port_outside_1_to_65535_or_not_an_integer_is_422(
    api: Api, db: Database, value: object
) -> None:
    robot = api.robot()
    r = _put(api, robot["id"], protocol="techman", host="10.0.0.7", ports={"listen_node": value})
    assert r.status_code == 422, r.text
    assert ["body", "ports", "listen_node"] in [e["loc"] for e in r.json()["errors"]]
    assert _stored(db.url, robot["id"]) is None


def test_a_protocol_without_its_connector_yet_is_501_and_nothing_is_sent_or_recorded(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Stored, a controller whose connector this tcpcal does not have answers 501
    /no-connector to a deployment, a reconcile and a pose read (not a 500), opens no
    connection (a listening socket on its port accepts none) and records no deployment.
    Every protocol has its connector now, so one is planted without it (`connector=None`,
    as a maker declares a protocol whose connector is not written yet)."""
    import socket
    from dataclasses import replace

    from app.vendors import registry

    robot = api.robot()
    # slot 1: a tool every protocol can address (Yaskawa numbers its tools 0-63), so the
    # answer is about the connector, not the tool's place
    tool = api.tool(robot["id"], "torch", slot=1)
    api.manual(tool["id"], [0.0, 0.0, 150.0])
    missing = [next(iter(REAL_PORTS))]
    unwritten = replace(registry.WIRE_PROTOCOLS[missing[0]], connector=None)
    monkeypatch.setitem(registry.WIRE_PROTOCOLS, missing[0], unwritten)
    assert not registry.has_connector(missing[0])
    with socket.socket() as controller:
        controller.bind(("127.0.0.1", 0))
        controller.listen(4)
        controller.setblocking(False)
        port = controller.getsockname()[1]
        service = next(iter(REAL_PORTS[missing[0]]))
        body = {"protocol": missing[0], "host": "127.0.0.1", "ports": {service: port}}
        assert _put(api, robot["id"], **body).status_code == 200
        answers = [
            api.post(f"/v1/tools/{tool['id']}/deployments", {}, scope="calibrate"),
            api.post(f"/v1/robots/{robot['id']}/reconcile", scope="read"),
            api.get(f"/v1/robots/{robot['id']}/controller/pose", scope="calibrate"),
        ]
        for answer in answers:
            assert answer.status_code == 501, answer.text
            assert answer.json()["type"].endswith("/no-connector")
            assert f"no {missing[0]} connector" in answer.json()["detail"]
        with pytest.raises(BlockingIOError):
            controller.accept()  # nobody knocked
    assert api.get(f"/v1/tools/{tool['id']}/deployments").json()["items"] == []


def test_a_backup_carries_the_ports(api: Api, db: Database, tmp_path: Path) -> None:
    robot = api.robot()
    ports = {"robot": 11040, "file": 11041}
    r = _put(api, robot["id"], protocol="yaskawa_hses", host="10.0.0.8", ports=ports)
    assert r.status_code == 200, r.text
    copy = tmp_path / "backup.dump"
    backup(db.url, copy)
    with fresh_database(db.backend, tmp_path, PG_URL, prefix="tcpcal_ports") as url:
        upgrade(url)  # the database a plant restores into
        restore(url, copy, force=True)
        restored = _stored(url, robot["id"])
    assert restored.port is None
    assert _ports(restored.ports) == ports
