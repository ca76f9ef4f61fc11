"""The console's guarded writes in a real headless Chromium: the fleet tints a tool whose
active version is out of tolerance and names the code; Activate asks for confirmation and a
reason (and says when a version is out of tolerance, then sends force); Roll back, named by
the version it returns to and offered only when the activation history has one; a read key
sees no write button; a report of a set whose fifth touch missed says touch 5.

Its own live server (SQLite, one worker): one KUKA robot with a torch (v1 accepted, v2 out of
tolerance, v3 accepted, then v2 forced live through the API), a probe calibrated from 8
touches whose fifth missed by 3 mm, and a gripper with two accepted versions.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import httpx
import numpy as np
import pytest
from playwright.sync_api import Page, expect

from app.kinematics.poses import pose_to_format
from testbed.live_server import LiveServer, fresh_database, live_server
from testbed.sim.touches import simulate_touches
from tests.browser.conftest import confirm, sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]


@dataclass
class Setup:
    server: LiveServer
    read_key: str
    tools: dict[str, str]
    fifth_missed: dict[str, Any]


def _poses(seed: int, *, noise: float, missed_at: int | None = None) -> list[Any]:
    touches = simulate_touches(
        8,
        seed=seed,
        tcp_mm=np.array([1.0, -0.5, 150.0]),
        touch_noise_mm=noise,
        outlier_fraction=0.0 if missed_at is None else 1 / 8,
        outlier_mm=3,
    )
    order = list(range(8))
    if missed_at is not None:  # move the missed touch to where the test wants it
        k = int(touches.outliers.nonzero()[0][0])
        order.remove(k)
        order.insert(missed_at, k)
    return [pose_to_format("kuka_abc", touches.R[i], touches.f[i]) for i in order]


def _calibrate(http: httpx.Client, tool_id: str, body: dict[str, Any]) -> dict[str, Any]:
    response = http.post(f"/v1/tools/{tool_id}/calibrations", json=body)
    assert response.status_code == 201, response.text
    result: dict[str, Any] = response.json()
    return result


def _seed(http: httpx.Client) -> tuple[dict[str, str], dict[str, Any], str]:
    robot = http.post("/v1/robots", json={"name": "weld7-kr16", "vendor": "KUKA"}).json()
    tools = {
        name: http.post(
            f"/v1/robots/{robot['id']}/tools", json={"name": name, "slot": slot}
        ).json()["id"]
        for slot, name in ((1, "torch"), (2, "probe"), (3, "gripper"))
    }
    torch = tools["torch"]
    _calibrate(http, torch, {"method": "manual", "tcp": {"position_mm": [1, -0.5, 150]}})
    bad = _calibrate(
        http, torch, {"method": "xyz_npoint", "format": "kuka_abc", "poses": _poses(2, noise=1.5)}
    )
    assert (bad["version"], bad["status"]) == (2, "out_of_tolerance")
    _calibrate(http, torch, {"method": "manual", "tcp": {"position_mm": [1, -0.5, 150.2]}})
    http.post(
        f"/v1/tools/{torch}/versions/2/activate",
        json={"force": True, "reason": "interim: spare torch in the shop"},
    ).raise_for_status()
    missed = _calibrate(
        http,
        tools["probe"],
        {"method": "xyz_npoint", "format": "kuka_abc", "poses": _poses(1, noise=0.03, missed_at=4)},
    )
    for z in (150.0, 150.4):
        body = {"method": "manual", "tcp": {"position_mm": [0, 0, z]}, "note": f"z {z}"}
        _calibrate(http, tools["gripper"], body)
    read_key = http.post("/v1/keys", json={"name": "cell-pc", "scope": "read"}).json()["key"]
    return tools, missed, str(read_key)


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Setup]:
    tmp = tmp_path_factory.mktemp("activation-console")
    with (
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
    ):
        with server.client() as http:
            tools, missed, read_key = _seed(http)
        yield Setup(server, read_key, tools, missed)


@pytest.fixture(scope="module")
def console_server(setup: Setup) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return setup.server


def _sign_in(page: Page, setup: Setup, path: str, key: str | None = None) -> None:
    sign_in_to(page, setup.server, path, key)


def _tool(setup: Setup, name: str) -> dict[str, Any]:
    with setup.server.client() as http:
        body: dict[str, Any] = http.get(f"/v1/tools/{setup.tools[name]}").json()
        return body


def test_fleet_tints_a_tool_whose_active_version_is_out_of_tolerance(
    page: Page, setup: Setup
) -> None:
    _sign_in(page, setup, "/")
    torch = page.locator(f"#fleet tr[data-tool-id='{setup.tools['torch']}']")
    expect(torch).to_have_class("attention")
    expect(torch.locator("td.reasons")).to_have_text("active_out_of_tolerance")
    # Its last calibration is fine: what is live is judged, not only the newest result.
    expect(torch).to_contain_text("accepted")
    gripper = page.locator(f"#fleet tr[data-tool-id='{setup.tools['gripper']}']")
    expect(gripper).not_to_have_class("attention")
    expect(gripper.locator("td.reasons")).to_have_text("")
    page.check("input[name=attention]")  # the server's ?attention=true
    expect(page.locator("#fleet tbody tr")).to_have_count(1)
    expect(page.locator("#fleet tbody tr")).to_contain_text("torch")


# Records where the versions table's top lies each time the page changes (a MutationObserver
# runs after every change, before the next fetch answers), so a section or a plot drawn after the
# table moved it is seen however fast the machine.
_RECORD_VERSIONS_TOP = """
window.versionsTops = [];
new MutationObserver(() => {
  const table = document.querySelector("#versions");
  if (!table) return;
  const top = Math.round(table.getBoundingClientRect().top + window.scrollY);
  if (window.versionsTops.at(-1) !== top) window.versionsTops.push(top);
}).observe(document, { childList: true, subtree: true, attributes: true });
"""


def test_the_tool_page_does_not_move_once_drawn(page: Page, setup: Setup) -> None:
    """The sections above the versions (the controller, the controllers' texts) and the plots
    between them are laid out when the table first appears: drawn after it, they pushed the
    table down under a click on its way to Activate (the plot by 240 px once Plotly loaded,
    seconds later on a busy machine), and the click landed elsewhere."""
    page.add_init_script(_RECORD_VERSIONS_TOP)
    _sign_in(page, setup, f"/ui/tools/{setup.tools['probe']}")
    expect(page.locator("main")).to_have_attribute("aria-busy", "false")
    expect(page.locator("#plot-tcp .main-svg").first).to_be_attached()
    expect(page.locator("#controllers [data-format=kuka] pre")).to_contain_text("$TOOL_DATA[2]")
    expect(page.locator("#controller-none")).to_be_visible()
    tops = page.evaluate("window.versionsTops")
    assert len(tops) == 1, f"the versions table moved after it was drawn: tops {tops} px"


def test_activate_asks_for_a_reason_and_forces_an_out_of_tolerance_version(
    page: Page, setup: Setup
) -> None:
    tool_id = setup.tools["torch"]
    _sign_in(page, setup, f"/ui/tools/{tool_id}")
    expect(page.locator("#who")).to_have_text("live-admin (admin)")
    # An accepted version: confirmation with a reason, nothing sent on Cancel.
    page.locator("#versions tr[data-version='3'] button.activate").click()
    dialog = page.locator("dialog#confirm")
    expect(dialog).to_contain_text("Activate version 3 of torch?")
    expect(dialog).not_to_contain_text("out of tolerance")
    dialog.get_by_role("button", name="Cancel").click()
    expect(dialog).to_have_count(0)
    assert _tool(setup, "torch")["active_version"] == 2
    page.locator("#versions tr[data-version='3'] button.activate").click()
    confirm(page, "new torch fitted, back to the good TCP")
    expect(page.locator("#versions tbody tr.active")).to_have_attribute("data-version", "3")
    last = page.locator("#activations tbody tr").first
    expect(last).to_contain_text("explicit")
    expect(last).to_contain_text("new torch fitted, back to the good TCP")

    # The out-of-tolerance version: the dialog says so and what it found; sent with force.
    page.locator("#versions tr[data-version='2'] button.activate").click()
    expect(dialog).to_contain_text("Version 2 is stored as out of tolerance")
    expect(dialog.locator("button[type=submit]")).to_have_text("Activate anyway")
    confirm(page, "interim again: the new torch is bent")
    expect(page.locator("#versions tbody tr.active")).to_have_attribute("data-version", "2")
    last = page.locator("#activations tbody tr").first
    expect(last).to_contain_text("forced")
    expect(last).to_contain_text("interim again: the new torch is bent")
    assert _tool(setup, "torch")["active_version"] == 2


def test_roll_back_button_names_the_version_active_before_and_returns_to_it(
    page: Page, setup: Setup
) -> None:
    tool_id = setup.tools["gripper"]
    _sign_in(page, setup, f"/ui/tools/{tool_id}")
    expect(page.locator("#versions tbody tr.active")).to_have_attribute("data-version", "2")
    expect(page.locator("#no-rollback")).to_have_count(0)
    expect(page.locator("#rollback")).to_have_text("Roll back to version 1")
    page.locator("#rollback").click()
    expect(page.locator("dialog#confirm")).to_contain_text("Roll back gripper to version 1?")
    confirm(page, "v2 touches the fixture")
    expect(page.locator("#versions tbody tr.active")).to_have_attribute("data-version", "1")
    last = page.locator("#activations tbody tr").first
    expect(last).to_contain_text("rollback")
    expect(last).to_contain_text("v2 touches the fixture")
    assert _tool(setup, "gripper")["active_version"] == 1
    # Nothing earlier is left (the rollback's previous version, 2, is not a target): no
    # button, which had asked for a reason and then shown 409 Nothing to roll back.
    expect(page.locator("#no-rollback")).to_contain_text("Nothing to roll back to")
    expect(page.get_by_role("button", name="Roll back")).to_have_count(0)


def test_a_tool_activated_once_offers_no_roll_back(page: Page, setup: Setup) -> None:
    _sign_in(page, setup, f"/ui/tools/{setup.tools['probe']}")
    expect(page.locator("#versions tbody tr.active")).to_have_attribute("data-version", "1")
    expect(page.locator("#activations tbody tr")).to_have_count(1)
    expect(page.locator("#no-rollback")).to_contain_text(
        "Nothing to roll back to: no version was active before version 1"
    )
    expect(page.get_by_role("button", name="Roll back")).to_have_count(0)
    with setup.server.client() as http:  # the server agrees: nothing to roll back to
        refused = http.post(f"/v1/tools/{setup.tools['probe']}/rollback", json={})
    assert refused.status_code == 409, refused.text


def test_roll_back_walks_back_through_the_activation_history(page: Page, setup: Setup) -> None:
    """The torch went live as v1, v3, then v2 forced (the activation test ends there too):
    rolling back returns to v3, then to v1 (not to v2, the version just left), then stops."""
    tool_id = setup.tools["torch"]
    _sign_in(page, setup, f"/ui/tools/{tool_id}")
    expect(page.locator("#versions tbody tr.active")).to_have_attribute("data-version", "2")
    for target, reason in ((3, "forced v2 no longer needed"), (1, "v3 was the spare torch")):
        button = page.locator("#rollback")
        expect(button).to_have_text(f"Roll back to version {target}")
        button.click()
        confirm(page, reason)
        active = page.locator("#versions tbody tr.active")
        expect(active).to_have_attribute("data-version", str(target))
        expect(page.locator("main")).to_have_attribute("aria-busy", "false")  # drawn whole
        assert _tool(setup, "torch")["active_version"] == target
    expect(page.locator("#rollback")).to_have_count(0)
    expect(page.locator("#no-rollback")).to_contain_text("before version 1")


def test_a_read_key_sees_no_write_buttons(page: Page, setup: Setup) -> None:
    _sign_in(page, setup, f"/ui/tools/{setup.tools['gripper']}", key=setup.read_key)
    expect(page.locator("#who")).to_have_text("cell-pc (read)")
    expect(page.locator("#versions tbody tr")).to_have_count(2)
    expect(page.locator("button.activate")).to_have_count(0)
    expect(page.get_by_role("button", name="Roll back")).to_have_count(0)
    expect(page.locator("#no-rollback")).to_have_count(0)
    expect(page.locator("#controllers [data-format=kuka] pre")).to_contain_text("$TOOL_DATA[3]")


def test_report_of_a_set_whose_fifth_touch_missed_says_touch_5(page: Page, setup: Setup) -> None:
    cal = setup.fifth_missed
    assert cal["quality"]["outliers"] == [4]  # the index, 0-based
    assert "touch 5 set aside" in cal["summary"]
    _sign_in(page, setup, f"/ui/calibrations/{cal['id']}")
    # The report draws a WebGL view first: slow on a busy machine's software renderer.
    expect(page.locator("#summary")).to_contain_text("touch 5 set aside", timeout=30_000)
    expect(page.locator("#warnings")).to_contain_text("touch 5 (")
    expect(page.locator("[data-field=outliers]")).to_have_text("5")
    expect(page.locator("#plot-residuals text.bartext").nth(4)).to_contain_text("outlier")
    assert "touch 4" not in page.locator("main").inner_text()
