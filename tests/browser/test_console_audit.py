"""The tool page's audit trail in a real headless Chromium: an admin key sees who changed
what and why (a tolerance tightened, a version rolled back to); another key is told that the
trail needs an admin key."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from playwright.sync_api import Page, expect

from testbed.live_server import LiveServer, fresh_database, http_client, live_server
from tests.browser.conftest import sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]


@dataclass
class Fleet:
    server: LiveServer
    tools: dict[str, str]  # "robot/tool" -> id


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    tmp = tmp_path_factory.mktemp("console-audit")
    with (
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
    ):
        with server.client() as http:
            robot = http.post("/v1/robots", json={"name": "kr16", "cell": "cell-12"}).json()
            tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "torch"}).json()
            tid = tool["id"]
            http.patch(f"/v1/tools/{tid}", json={"tolerance": {"max_rms_mm": 0.2}})
            for z, note in ((150, "data sheet"), (151, "after crash")):
                http.post(
                    f"/v1/tools/{tid}/calibrations",
                    json={"method": "manual", "tcp": {"position_mm": [0, 0, z]}, "note": note},
                ).raise_for_status()
            http.post(f"/v1/tools/{tid}/versions/1/activate").raise_for_status()
        yield Fleet(server, {"kr16/torch": tid})


@pytest.fixture(scope="module")
def console_server(fleet: Fleet) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let pages reach."""
    return fleet.server


def _sign_in(tab: Page, fleet: Fleet, key: str, path: str) -> None:
    sign_in_to(tab, fleet.server, path, key)


def test_an_admin_sees_the_tools_trail_newest_first(page: Page, fleet: Fleet) -> None:
    tid = fleet.tools["kr16/torch"]
    _sign_in(page, fleet, fleet.server.admin_key, f"/ui/tools/{tid}")
    rows = page.locator("#audit tbody tr")
    expect(rows).to_have_count(
        9
    )  # create, update, 2 x (version, activation, calibration), rollback
    first = rows.first
    expect(first).to_have_attribute("data-action", "version.activate")
    expect(first).to_contain_text("live-admin")
    expect(first).to_contain_text("explicit (was v2)")
    update = page.locator("#audit tr[data-action='tool.update']")
    expect(update).to_contain_text("tolerance.max_rms_mm 0.5 → 0.2")
    expect(page.locator("#audit tr[data-action='calibration.create']").first).to_contain_text(
        "manual accepted: after crash"
    )
    expect(page.locator("#audit-needs-admin")).to_have_count(0)


def test_a_read_key_is_told_the_trail_needs_an_admin_key(page: Page, fleet: Fleet) -> None:
    with fleet.server.client() as http:
        made = http.post("/v1/keys", json={"name": "viewer", "scope": "read"})
    key = made.json()["key"]
    tid = fleet.tools["kr16/torch"]
    _sign_in(page, fleet, key, f"/ui/tools/{tid}")
    expect(page.locator("h1")).to_contain_text("torch")
    expect(page.locator("#audit-needs-admin")).to_contain_text("needs an admin key")
    expect(page.locator("#audit")).to_have_count(0)
    # the rest of the page is there for the read key
    expect(page.locator("#versions tbody tr")).to_have_count(2)
    with http_client(fleet.server.url) as http:
        denied = http.get("/v1/audit", headers={"Authorization": f"Bearer {key}"})
    assert denied.status_code == 403
