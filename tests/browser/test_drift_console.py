"""The drift trend in a real headless Chromium: a tool whose checks drift towards check_mm is
tinted on the fleet with its rate and the `drifting` code; its page gives the rate ± sigma
under both plots and draws the trend on the checks plot.

The history spans 100 days, so it is written in-process with the clock set back
(app.storage.models.clock_at, as `tcpcal demo` does) before the live server starts on the database.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import pytest
from playwright.sync_api import Page, expect

from app.methods.requests import CALIBRATION_REQUESTS
from app.schemas.references import CheckCreate, ReferencePointCreate
from app.schemas.robots import RobotCreate
from app.schemas.tools import ToolCreate
from app.security.auth import Principal
from app.services.calibrations import writes
from app.services.checks import checks
from app.services.references import references
from app.services.robots import robots
from app.services.tools import tools
from app.storage.db import engine_for, session_scope
from app.storage.migrate import upgrade
from app.storage.models import clock_at
from testbed.live_server import LiveServer, fresh_database, live_server
from tests.browser.conftest import sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]

ACTOR = Principal(key_id="test", name="test", scope="admin")


@dataclass
class Setup:
    server: LiveServer
    drifting: str
    steady: str


def _seed(url: str) -> tuple[str, str]:
    """'drifting': checks 0.009 mm/day further off over 100 days (0.9 mm now, check_mm 1.0);
    'steady': checks standing at 0.3 mm."""
    start = datetime.now(UTC) - timedelta(days=100)
    ids = {}
    with (
        session_scope(write=True, engine=engine_for(url)) as session,
        clock_at(start - timedelta(days=1)),
    ):
        robot = robots.create_robot(
            session, data=RobotCreate(name="weld12-kr16", vendor="KUKA"), actor=ACTOR
        )
        pin = references.register_reference_point(
            session,
            robot_id=robot.id,
            data=ReferencePointCreate(name="pin", position_mm=[500, 0, 300]),
            actor=ACTOR,
        )
        for slot, name in enumerate(["drifting", "steady"], start=1):
            tool = tools.create_tool(
                session, robot_id=robot.id, data=ToolCreate(name=name, slot=slot), actor=ACTOR
            )
            body = {"method": "manual", "tcp": {"position_mm": [0, 0, 100]}}
            writes.submit(
                session,
                tool_id=tool.id,
                request=CALIBRATION_REQUESTS.validate_python(body),
                raw_body=body,
                idempotency_key=None,
                actor=ACTOR,
            )
            ids[name] = tool.id
    for day in range(0, 101, 10):  # one transaction per check, as over HTTP
        with session_scope(write=True, engine=engine_for(url)) as session:
            for name, dx in (("drifting", 0.009 * day), ("steady", 0.3)):
                # the flange turned 180 deg about X: the tip lands dx off the pin along X
                data = CheckCreate.model_validate(
                    {
                        "reference_point_id": pin.id,
                        "format": "xyz_wxyz",
                        "poses": [[500 + dx + 0.003 * (day % 3), 0, 400, 0, 1, 0, 0]],
                    }
                )
                with clock_at(start + timedelta(days=day)):
                    checks.run_check(session, tool_id=ids[name], data=data, actor=ACTOR)
    return ids["drifting"], ids["steady"]


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Setup]:
    tmp = tmp_path_factory.mktemp("drift-console")
    with fresh_database("sqlite", tmp, None) as url:
        upgrade(url)
        drifting, steady = _seed(url)
        engine_for(url).dispose()
        with live_server(url, workers=1, solvers=0) as server:
            yield Setup(server, drifting, steady)


@pytest.fixture(scope="module")
def console_server(setup: Setup) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return setup.server


RATE = re.compile(r"0\.2[5-9]\d ± 0\.0\d\d mm/month")


def test_fleet_tints_a_drifting_tool_and_shows_its_rate(page: Page, setup: Setup) -> None:
    sign_in_to(page, setup.server, "/")
    row = page.locator(f"#fleet tr[data-tool-id='{setup.drifting}']")
    expect(row).to_have_class("attention")
    expect(row.locator("td.drift")).to_have_text(RATE)
    expect(row.locator("td.reasons")).to_have_text("drifting")
    steady = page.locator(f"#fleet tr[data-tool-id='{setup.steady}']")
    expect(steady).not_to_have_class("attention")
    expect(steady.locator("td.drift")).to_contain_text("mm/month")


def test_tool_page_gives_the_rate_and_draws_the_trend(page: Page, setup: Setup) -> None:
    sign_in_to(page, setup.server, f"/ui/tools/{setup.drifting}")
    line = page.locator("#drift-checks")
    expect(line).to_have_class(re.compile(r"\battention\b"))
    expect(line.locator(".rate")).to_have_text(re.compile(r"Drift " + RATE.pattern))
    expect(line).to_contain_text("projected out of check_mm by")
    # one manual version: no measured series under the TCP plot, and it says why
    expect(page.locator("#drift-versions")).to_contain_text("no trend yet")
    expect(page.locator("#plot-checks .scatterlayer .trace")).to_have_count(3)
    names = page.evaluate("document.getElementById('plot-checks').data.map((t) => t.name)")
    assert names == ["distance mm", "check_mm", "trend"]
    steady = page.locator("#drift-checks")
    page.goto(f"{setup.server.url}/ui/tools/{setup.steady}")  # signed in for the tab
    expect(steady).not_to_have_class(re.compile(r"\battention\b"))
    expect(steady).to_contain_text("not projected out of check_mm")
