"""A robot's controller connection: validated field by field, the password encrypted at
rest and never given back, logged or backed up in clear."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import text

from app.storage.backup import backup
from app.storage.db import get_engine
from tests.conftest import Api, Database

PASSWORD = "Pa55-w0rd-that-must-not-leak-7f3a"
SECRET = "a-long-random-secret-for-the-tests-0123456789"


@pytest.fixture
def secret_key(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    from app.config import get_settings

    monkeypatch.setenv("TCPCAL_SECRET_KEY", SECRET)
    get_settings.cache_clear()
    yield SECRET
    get_settings.cache_clear()


def _put(api: Api, robot_id: str, scope: str = "admin", **body: Any) -> Any:
    return api.request("PUT", f"/v1/robots/{robot_id}/controller", scope, json=body)


def _stored(robot_id: str) -> Any:
    with get_engine().connect() as conn:
        return conn.execute(
            text("SELECT * FROM robot_controllers WHERE robot_id = :r"), {"r": robot_id}
        ).one_or_none()


def test_put_fills_the_protocols_default_port_and_get_and_delete(api: Api) -> None:
    robot = api.robot()
    for protocol, port in [
        ("kuka_kvp", 7000),
        ("fanuc_rmi", 16001),
        ("abb_rws1", 80),
        ("abb_rws2", 443),
    ]:
        r = _put(api, robot["id"], protocol=protocol, host="10.0.0.7")
        assert r.status_code == 200, r.text
        assert r.json()["port"] == port
        assert r.json()["has_password"] is False
        assert r.json()["timeout_s"] == 5.0
        assert r.json()["tls_verify"] is True
    got = api.get(f"/v1/robots/{robot['id']}/controller")
    assert got.status_code == 200
    assert got.json()["protocol"] == "abb_rws2"
    assert _put(api, robot["id"], "read", protocol="kuka_kvp", host="a").status_code == 403
    assert api.delete(f"/v1/robots/{robot['id']}/controller").status_code == 204
    gone = api.get(f"/v1/robots/{robot['id']}/controller")
    assert gone.status_code == 404  # contract v1.3: 404 /no-controller
    assert gone.json()["type"].endswith("/no-controller")
    actions = [e["action"] for e in _audit(robot["id"])]
    assert actions.count("controller.set") == 4
    assert actions.count("controller.delete") == 1


def test_the_controller_says_which_pose_format_its_pendant_shows(api: Api) -> None:
    """`pose_format` (issue 51): what `tcpcal calibrate --guided --capture` and the console
    type a captured session in when no format is given, from the registry's makers, not a
    copy of their table in each client."""
    robot = api.robot()
    pendants = {
        "kuka_kvp": "kuka_abc",
        "fanuc_rmi": "fanuc_wpr",
        "abb_rws1": "xyz_wxyz",
        "abb_rws2": "xyz_wxyz",
    }
    for protocol, fmt in pendants.items():
        put = _put(api, robot["id"], protocol=protocol, host="10.0.0.7")
        assert put.status_code == 200, put.text
        assert put.json()["pose_format"] == fmt
        assert api.get(f"/v1/robots/{robot['id']}/controller").json()["pose_format"] == fmt


def _audit(robot_id: str) -> list[dict[str, Any]]:
    with get_engine().connect() as conn:
        rows = conn.execute(
            text("SELECT action, details FROM audit_events WHERE robot_id = :r ORDER BY id"),
            {"r": robot_id},
        )
        return [{"action": r.action, "details": r.details} for r in rows]


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("host", "h" * 300),
        ("host", "not a host!"),
        ("host", ""),
        ("port", 0),
        ("port", 70000),
        ("port", "7000"),
        ("protocol", "kuka_rsi"),
        ("timeout_s", 0.05),
        ("timeout_s", 61),
        ("tls_verify", "yes"),
    ],
)
def test_bad_fields_are_422_naming_the_field_and_store_nothing(
    api: Api, field: str, value: object
) -> None:
    robot = api.robot()
    body: dict[str, Any] = {"protocol": "kuka_kvp", "host": "192.168.1.20", field: value}
    r = _put(api, robot["id"], **body)
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    assert ["body", field] in [e["loc"] for e in r.json()["errors"]]
    assert _stored(robot["id"]) is None


def test_hosts_that_are_names_or_addresses_are_taken(api: Api) -> None:
    """Each is stored as sent and served back: the PUT's answer, a later GET and the row the
    connectors are given (app.services.robots.connection.settings_of) all hold it."""
    from app.services.robots.connection import get_controller, settings_of
    from app.storage.db import session_scope

    robot = api.robot()
    for host in ["192.168.1.20", "fe80::1", "kr16-cell12.plant.local", "a" * 63 + ".b"]:
        r = _put(api, robot["id"], protocol="fanuc_rmi", host=host)
        assert r.status_code == 200, r.text
        assert r.json()["host"] == host
        assert api.get(f"/v1/robots/{robot['id']}/controller").json()["host"] == host
        assert _stored(robot["id"]).host == host
        with session_scope(write=False) as session:
            assert settings_of(get_controller(session, robot["id"])).host == host


def test_a_password_without_a_secret_key_is_422_saying_what_to_set(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    from app.config import get_settings

    monkeypatch.delenv("TCPCAL_SECRET_KEY", raising=False)
    get_settings.cache_clear()
    robot = api.robot()
    r = _put(api, robot["id"], protocol="abb_rws1", host="10.0.0.9", password=PASSWORD)
    assert r.status_code == 422, r.text
    assert "TCPCAL_SECRET_KEY" in r.json()["detail"]
    assert r.json()["errors"][0]["loc"] == ["body", "password"]
    assert PASSWORD not in r.text
    assert _stored(robot["id"]) is None


def test_the_password_is_never_served_logged_or_backed_up_in_clear(
    api: Api,
    db: Database,
    secret_key: str,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    capfd: pytest.CaptureFixture[str],
) -> None:
    caplog.set_level(logging.DEBUG)
    robot = api.robot()
    texts = []
    r = _put(
        api, robot["id"], protocol="abb_rws2", host="10.0.0.9", username="Admin", password=PASSWORD
    )
    assert r.status_code == 200, r.text
    assert r.json()["has_password"] is True
    assert "password" not in r.json()
    texts.append(r.text)
    # Left out, the stored password is kept; the row holds ciphertext only.
    r = _put(api, robot["id"], protocol="abb_rws2", host="10.0.0.10", username="Admin")
    assert r.json()["has_password"] is True
    texts.append(r.text)
    stored = _stored(robot["id"])
    assert stored.password_encrypted
    assert PASSWORD not in stored.password_encrypted
    from app.security import secretbox

    assert secretbox.decrypt(stored.password_encrypted) == PASSWORD
    texts.append(api.get(f"/v1/robots/{robot['id']}/controller").text)
    texts.append(api.get("/v1/tools").text)
    texts.append(api.get("/openapi.json").text)
    if db.backend == "sqlite":  # `tcpcal db backup` copies the database as it is
        copy = tmp_path / "backup.sqlite3"
        backup(db.url, copy)
        raw = copy.read_bytes()
        assert PASSWORD.encode() not in raw
        assert stored.password_encrypted.encode() in raw  # the ciphertext is what is kept
    captured = capfd.readouterr()
    texts += [captured.out, captured.err, caplog.text]
    texts += [str(e["details"]) for e in _audit(robot["id"])]
    for t in texts:
        assert PASSWORD not in t
    # null removes it
    r = _put(api, robot["id"], protocol="abb_rws2", host="10.0.0.10", password=None)
    assert r.json()["has_password"] is False
    assert _stored(robot["id"]).password_encrypted is None


def test_a_password_under_another_secret_key_is_refused_when_used(
    api: Api, secret_key: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A controller stored with a password, then the secret key changed: a reconcile and a
    deployment through the API are 409 /secret-unavailable saying what to do, and neither
    opens a connection to the controller (a listening socket at its address accepts none)
    nor records a deployment."""
    import socket

    from app.config import get_settings

    robot = api.robot()
    load = {"mass_kg": 2.5, "cog_mm": [0, 0, 80]}
    tool = api.tool(robot["id"], "torch", controller_symbol="T_ROB1/user/tTorch", load=load)
    api.manual(tool["id"], [0.0, 0.0, 150.0])
    with socket.socket() as controller:
        controller.bind(("127.0.0.1", 0))
        controller.listen(4)
        controller.setblocking(False)
        port = controller.getsockname()[1]
        body = {"protocol": "abb_rws2", "host": "127.0.0.1", "port": port, "timeout_s": 0.5}
        r = _put(api, robot["id"], **body, username="Admin", password=PASSWORD)
        assert r.status_code == 200, r.text
        monkeypatch.setenv("TCPCAL_SECRET_KEY", "another-secret-entirely-9876543210")
        get_settings.cache_clear()
        reconcile = api.post(f"/v1/robots/{robot['id']}/reconcile", scope="read")
        deploy = api.post(f"/v1/tools/{tool['id']}/deployments", {}, scope="calibrate")
        for refused in (reconcile, deploy):
            assert refused.status_code == 409, refused.text
            problem = refused.json()
            assert problem["type"].endswith("/secret-unavailable")
            assert "cannot be decrypted" in problem["detail"]
            assert "set the previous one, or send the password again" in problem["detail"]
            assert PASSWORD not in refused.text
        with pytest.raises(BlockingIOError):
            controller.accept()  # nobody knocked
    assert api.get(f"/v1/tools/{tool['id']}/deployments").json()["items"] == []


def test_abb_symbol_without_a_module_is_422_and_stores_nothing(api: Api) -> None:
    robot = api.robot()
    r = api.post(
        f"/v1/robots/{robot['id']}/tools", {"name": "torch", "controller_symbol": "T_ROB1/tTorch"}
    )
    assert r.status_code == 422, r.text
    assert r.json()["errors"][0]["loc"] == ["body", "controller_symbol"]
    assert api.get(f"/v1/robots/{robot['id']}/tools").json()["items"] == []
    tool = api.tool(robot["id"], controller_symbol="T_ROB1/user/tTorch")
    assert tool["controller_symbol"] == "T_ROB1/user/tTorch"
    r = api.patch(f"/v1/tools/{tool['id']}", {"controller_symbol": "tTorch"})
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"] == ["body", "controller_symbol"]
    assert api.get(f"/v1/tools/{tool['id']}").json()["controller_symbol"] == "T_ROB1/user/tTorch"


def test_kuka_slot_17_is_422_naming_the_slot_and_stores_nothing(api: Api) -> None:
    robot = api.robot()
    assert _put(api, robot["id"], protocol="kuka_kvp", host="10.0.0.5").status_code == 200
    r = api.post(f"/v1/robots/{robot['id']}/tools", {"name": "gripper", "slot": 17})
    assert r.status_code == 422, r.text
    assert r.json()["errors"][0]["loc"] == ["body", "slot"]
    assert "1-16" in r.json()["detail"]
    assert api.get(f"/v1/robots/{robot['id']}/tools").json()["items"] == []
    tool = api.tool(robot["id"], slot=16)
    r = api.patch(f"/v1/tools/{tool['id']}", {"slot": 17})
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"] == ["body", "slot"]
    assert api.get(f"/v1/tools/{tool['id']}").json()["slot"] == 16


def test_a_protocol_whose_tool_numbers_exclude_a_tools_slot_is_422(api: Api) -> None:
    robot = api.robot()
    api.tool(robot["id"], name="spindle", slot=12)
    r = _put(api, robot["id"], protocol="fanuc_rmi", host="10.0.0.5")
    assert r.status_code == 422, r.text
    assert r.json()["errors"][0]["loc"] == ["body", "protocol"]
    assert "spindle" in r.json()["detail"]
    assert _stored(robot["id"]) is None


@pytest.mark.parametrize(
    ("vendor", "protocol", "fitting"),
    [
        ("KUKA", "techman", "kuka_kvp"),
        ("ABB", "kuka_kvp", "abb_rws1, abb_rws2"),
        ("Universal Robots", "fanuc_rmi", "ur_rtde"),
        ("TM5", "ur_rtde", "techman"),
    ],
)
def test_a_protocol_of_another_maker_than_the_robots_vendor_is_refused(
    api: Api, vendor: str, protocol: str, fitting: str
) -> None:
    """Issue 51 #8: a KUKA robot connected with protocol techman was stored, and every
    capture then talked Techman to a KUKA controller (or timed out at its port)."""
    robot = api.robot("r-vendor", vendor=vendor)
    r = _put(api, robot["id"], protocol=protocol, host="10.0.0.7")
    assert r.status_code == 422, r.text
    problem = r.json()
    assert problem["errors"][0]["loc"] == ["body", "protocol"]
    assert f"robot r-vendor's vendor is {vendor!r}" in problem["detail"], problem["detail"]
    assert f"its controllers speak {fitting}" in problem["detail"], problem["detail"]
    assert protocol in problem["detail"]
    assert _stored(robot["id"]) is None
    first = fitting.split(", ")[0]
    assert _put(api, robot["id"], protocol=first, host="10.0.0.7").status_code == 200


def test_a_robot_of_no_known_vendor_takes_any_protocol(api: Api) -> None:
    for vendor in (None, "Acme Robotics"):
        robot = api.robot(f"r-{vendor}", **({} if vendor is None else {"vendor": vendor}))
        assert _put(api, robot["id"], protocol="techman", host="10.0.0.7").status_code == 200


@pytest.mark.parametrize(
    ("before", "protocol", "vendor", "fitting"),
    [
        (None, "techman", "KUKA", "kuka_kvp"),
        ("KUKA", "kuka_kvp", "TM5", "techman"),
    ],
)
def test_a_vendor_whose_controllers_do_not_speak_the_controllers_protocol_is_refused(
    api: Api, before: str | None, protocol: str, vendor: str, fitting: str
) -> None:
    """Issue 51 #8 through PATCH: a robot connected with techman and then patched to vendor
    KUKA was 200, its controller still techman, so every capture talked Techman to a KRC."""
    robot = api.robot("r-patch", **({} if before is None else {"vendor": before}))
    assert _put(api, robot["id"], protocol=protocol, host="10.0.0.7").status_code == 200
    controller = api.get(f"/v1/robots/{robot['id']}/controller").json()
    with get_engine().connect() as conn:
        audited = conn.execute(text("SELECT count(*) FROM audit_events")).scalar_one()
    r = api.patch(f"/v1/robots/{robot['id']}", {"vendor": vendor, "model": "new"})
    assert r.status_code == 422, r.text
    problem = r.json()
    assert problem["errors"][0]["loc"] == ["body", "vendor"]
    detail = problem["detail"]
    assert f"controller speaks {protocol}" in detail, detail
    assert f"{vendor!r} robot's controllers speak {fitting}" in detail, detail
    assert f"tcpcal connect r-patch --protocol {fitting} --host HOST" in detail, detail
    first = "PUT" if before is None else "DELETE"  # a KUKA robot's PUT refuses techman
    assert f"{first} /v1/robots/{robot['id']}/controller" in detail, detail
    got = api.get(f"/v1/robots/{robot['id']}").json()
    assert (got["vendor"], got["model"]) == (before, robot["model"])
    assert api.get(f"/v1/robots/{robot['id']}/controller").json() == controller
    with get_engine().connect() as conn:
        assert conn.execute(text("SELECT count(*) FROM audit_events")).scalar_one() == audited
    if before is None:  # as the 422 says: the controller first, then the vendor
        assert _put(api, robot["id"], protocol=fitting, host="10.0.0.7").status_code == 200
        assert api.patch(f"/v1/robots/{robot['id']}", {"vendor": vendor}).status_code == 200
    else:  # the controller out, the vendor, the controller again
        assert _put(api, robot["id"], protocol=fitting, host="10.0.0.7").status_code == 422
        assert api.delete(f"/v1/robots/{robot['id']}/controller").status_code == 204
        assert api.patch(f"/v1/robots/{robot['id']}", {"vendor": vendor}).status_code == 200
        assert _put(api, robot["id"], protocol=fitting, host="10.0.0.7").status_code == 200


def test_a_robot_patched_to_a_vendor_of_no_known_maker_keeps_any_controller(api: Api) -> None:
    robot = api.robot("r-any", vendor="KUKA")
    assert _put(api, robot["id"], protocol="kuka_kvp", host="10.0.0.7").status_code == 200
    for vendor in ("Acme Robotics", None):
        r = api.patch(f"/v1/robots/{robot['id']}", {"vendor": vendor})
        assert r.status_code == 200, r.text
        assert r.json()["vendor"] == vendor


def test_a_robot_says_which_pose_format_its_makers_pendant_shows(api: Api) -> None:
    """A robot's `pose_format` (issue 46): its maker's, found by its vendor as the registry
    finds it, so the console types a robot without a controller in it with no copy of the
    makers' table (calibrate.js kept VENDOR_FORMATS); null for a vendor no maker answers to."""
    for vendor, fmt in {"KUKA Roboter": "kuka_abc", "Yaskawa Motoman": "yaskawa_rxyz"}.items():
        robot = api.robot(vendor, vendor=vendor)
        assert robot["pose_format"] == fmt
        assert api.get(f"/v1/robots/{robot['id']}").json()["pose_format"] == fmt
    assert api.robot("acme", vendor="Acme")["pose_format"] is None
    assert api.robot("bare")["pose_format"] is None
