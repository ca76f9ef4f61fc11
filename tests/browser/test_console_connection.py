"""Connecting a robot's controller from the console, in a real Chromium: an admin fills in
a UR connection with ports of its own and the tool page says where the controller is reached
(each service's port); the protocols and their default ports are the API's own (its schema's
enum and `x-default-ports`); a value the server refuses is said next to its field, nothing
stored; a stored password is removed with its own control; a calibrate key sees no form.

A live server (SQLite, one worker) with a robot and a tool and no controller connection."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, live_server
from tests.browser.conftest import sign_in_to
from tests.polling import wait_for

pytestmark = [pytest.mark.live, pytest.mark.browser]

RTDE, SECONDARY = 30104, 30102
SECRET = "a-long-random-secret-for-the-console-tests-0123456789"


@dataclass
class Cell:
    server: LiveServer
    robot_id: str
    tool_id: str
    calibrate_key: str


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("console-connection")
    with pytest.MonkeyPatch.context() as env:
        env.setenv("TCPCAL_SECRET_KEY", SECRET)  # a password can be stored
        with (
            fresh_database("sqlite", tmp, None) as url,
            live_server(url, workers=1, solvers=0) as server,
            server.client() as http,
        ):
            robot = http.post("/v1/robots", json={"name": "ur10e-glue", "cell": "glue-1"}).json()
            tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "glue-gun"}).json()
            key = http.post("/v1/keys", json={"name": "cell-pc", "scope": "calibrate"})
            key.raise_for_status()
            yield Cell(server, robot["id"], tool["id"], key.json()["key"])


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return cell.server


def test_an_admin_connects_a_ur_with_ports_of_its_own(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.tool_id}")
    expect(page.locator("#controller-none")).to_contain_text("connect it below")
    form = page.locator("#connection-form")
    expect(form).to_be_visible()
    # the protocols the API offers, in its order
    with cell.server.client() as http:
        protocol = http.get("/openapi.json").json()["components"]["schemas"]["ControllerIn"][
            "properties"
        ]["protocol"]
    options = form.locator("select[name=protocol] option")
    expect(options).to_have_text(protocol["enum"])
    form.locator("select[name=protocol]").select_option("ur_rtde")
    # a protocol of several services: one port a service, its default shown
    expect(form.locator("input[name=port]")).to_have_count(0)
    expect(form.locator("input[name='ports.rtde']")).to_have_attribute("placeholder", "30004")
    expect(form.locator("[data-field='ports.secondary']")).to_contain_text("default 30002")
    form.locator("input[name=host]").fill("127.0.0.1")
    form.locator("input[name='ports.rtde']").fill(str(RTDE))
    form.locator("input[name='ports.secondary']").fill(str(SECONDARY))
    form.locator("input[name=timeout_s]").fill("2")
    form.locator("#connection-save").click()
    expect(page.locator("#controller-state")).to_contain_text(
        f"ur_rtde at 127.0.0.1 (rtde {RTDE}, secondary {SECONDARY})"
    )
    # what live means, now that the robot is reached by a live protocol
    expect(page.locator("#controller-scope")).to_contain_text(
        "the next program start sets its own TCP"
    )
    with cell.server.client() as http:
        stored = http.get(f"/v1/robots/{cell.robot_id}/controller").json()
    assert stored["ports"] == {"rtde": RTDE, "secondary": SECONDARY}
    assert stored["timeout_s"] == 2.0


def test_a_refused_value_is_said_next_to_its_field(page: Page, cell: Cell) -> None:
    with cell.server.client() as http:
        http.delete(f"/v1/robots/{cell.robot_id}/controller")
    sign_in_to(page, cell.server, f"/ui/tools/{cell.tool_id}")
    form = page.locator("#connection-form")
    form.locator("select[name=protocol]").select_option("techman")
    expect(form.locator("input[name='ports.listen_node']")).to_have_attribute("placeholder", "5890")
    form.locator("input[name=host]").fill("127.0.0.1")
    form.locator("input[name='ports.ethernet_slave']").fill("70000")
    form.locator("#connection-save").click()
    said = form.locator("[data-field='ports.ethernet_slave'] .field-problem")
    expect(said).to_be_visible()
    expect(said).to_contain_text("ports.ethernet_slave")
    expect(said).to_contain_text("65535")
    expect(form.locator("[data-field=host] .field-problem")).to_be_hidden()
    expect(page.locator("#connection-refused")).to_contain_text("nothing was stored")
    with cell.server.client() as http:
        assert http.get(f"/v1/robots/{cell.robot_id}/controller").status_code == 404


def test_a_stored_password_is_removed_with_its_own_control(page: Page, cell: Cell) -> None:
    """Issue 51: the form could keep a stored password (empty field) or replace it, never
    remove it: a controller whose user needs none kept being sent the old one."""
    body = {"protocol": "abb_rws2", "host": "127.0.0.1", "password": "old-pw-4711"}
    controller = f"/v1/robots/{cell.robot_id}/controller"
    with cell.server.client() as http:
        put = http.put(controller, json=body)
        assert put.status_code == 200, put.text
        assert put.json()["has_password"] is True
        try:
            sign_in_to(page, cell.server, f"/ui/tools/{cell.tool_id}")
            page.locator("details#connection summary").click()
            form = page.locator("#connection-form")
            forget = form.locator("#connection-forget-password")
            expect(form.locator("[data-field=password]")).to_contain_text("a password is stored")
            expect(forget).not_to_be_checked()
            forget.check()
            expect(form.locator("#connection-password")).to_be_disabled()
            form.locator("#connection-save").click()
            wait_for(lambda: not http.get(controller).json()["has_password"], 10, "the removal")
            stored = http.get(controller).json()
            assert (stored["protocol"], stored["host"]) == ("abb_rws2", "127.0.0.1")
            # drawn again (still signed in): no password to remove
            page.reload()
            expect(page.locator("main")).to_have_attribute("aria-busy", "false")
            page.locator("details#connection summary").click()
            expect(page.locator("#connection-form [data-field=password]")).to_contain_text(
                "write-only: never shown again"
            )
            expect(page.locator("#connection-forget-password")).to_have_count(0)
        finally:
            http.delete(controller)


def test_a_calibrate_key_sees_no_form(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.tool_id}", key=cell.calibrate_key)
    expect(page.locator("#controller-none")).to_contain_text("an admin connects it")
    # the form's box is drawn with the section (its fields once the schema is read)
    expect(page.locator("details#connection")).to_have_count(0)
    expect(page.locator("#connection-form")).to_have_count(0)
