"""The tool page as a person at the cell sees it, in a real Chromium (issue 37): a tool
without a slot says why it has no .LS or TOOL.CND to download, no card reads "None", the
page fits a 1400 px window and a 768 px tablet, the TCP chart steps one version at a time,
and each deployment status is said in words a technician acts on (contract v1.3)."""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import timedelta
from itertools import pairwise
from typing import Any

import pytest
from playwright.sync_api import Page, Route, expect

from app.storage.db import engine_for, session_scope
from app.storage.models import Deployment, utcnow
from testbed.live_server import LiveServer, fresh_database, live_server
from tests.browser.conftest import sign_in_to

pytestmark = [pytest.mark.live, pytest.mark.browser]

V1 = {"position_mm": [0.0, 0.0, 150.0], "quaternion": [1.0, 0.0, 0.0, 0.0]}
V2 = {"position_mm": [0.5, -0.25, 151.0], "quaternion": [1.0, 0.0, 0.0, 0.0]}
#: An RWS error as long as they come: a URL no line can break at a space.
LONG_DETAIL = (
    "the controller refused: http://127.0.0.1:8080/rw/rapid/symbol/data/RAPID/T_ROB1/"
    "tcpcal_tools/tool_glue_nozzle_with_a_long_name;value?action=set&mastership=implicit "
    "answered 400 Bad Request"
)


WORDS = {
    "verified": "the controller holds v1 (read back within 0.0001 mm, 0.0000 deg)",
    "not_written": "nothing was written: the controller still holds what it held",
    "unverified": "written, not confirmed: the controller may hold v2 or v1; "
    "the next reconcile round will tell",
    "mismatch": "written, but the controller reads back 0.2501 mm and 0.0123 deg off v2",
}


@dataclass
class Cell:
    server: LiveServer
    loose: str  # no slot, no load: several formats cannot hold it
    quick: str  # three versions made seconds apart
    torch: str  # on a robot with a controller; a deployment of every status
    deployments: dict[str, int]  # status (or its variant) -> the planted deployment's id


def _closed_port() -> int:
    """A loopback port nothing listens on: a deployment there is refused before any write."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _plant_deployments(url: str, tool_id: str, robot_id: str) -> dict[str, int]:
    """One deployment of each status, written as the service records them: the page shows
    what the API serves, and a live controller cannot be made to stop at each point on cue."""
    now = utcnow()
    rows: dict[str, dict[str, Any]] = {
        "verified": {"version": 1, "previous": None, "read_back": V1, "deviation_mm": 0.0001,
                     "deviation_deg": 0.0, "error": None},
        # as the service words it since v1.3: its detail ends with the status in words
        "not_written": {"version": 2, "previous": None, "read_back": None, "deviation_mm": None,
                        "deviation_deg": None, "error": {"type": "controller-refused",
                        "detail": f"{LONG_DETAIL}; {WORDS['not_written']}",
                        "controller_message": None}},
        # as recorded before v1.3 said it in words: the page says them
        "unverified": {"version": 2, "previous": V1, "read_back": None, "deviation_mm": None,
                       "deviation_deg": None, "error": {"type": "controller-unreachable",
                       "detail": "the controller stopped answering after $TOOL_DATA[3] was sent",
                       "controller_message": None}, "reason": "new nozzle",
                       "settled": {"at": "2026-11-27T08:00:00+00:00", "holds": "previous",
                                   "frame": V1}},
        # a not_written row as worded before v1.3: the detail's "nothing was written" alone
        "not_written_before": {"status": "not_written", "version": 2, "previous": None,
                               "read_back": None, "deviation_mm": None, "deviation_deg": None,
                               "error": {"type": "controller-unreachable",
                               "detail": "the controller at 127.0.0.1:1 could not be reached "
                               "within 1 s: connection refused; nothing was written",
                               "controller_message": None}},
        "mismatch": {"version": 2, "previous": V1, "read_back": V2, "deviation_mm": 0.2501,
                     "deviation_deg": 0.0123, "error": {"type": "controller-mismatch",
                     "detail": "$TOOL_DATA[3] reads back 0.2501 mm and 0.0123 deg from what "
                     "was written", "controller_message": None}},
    }  # fmt: skip
    ids = {}
    with session_scope(write=True, engine=engine_for(url)) as session:
        for minutes, (name, fields) in enumerate(rows.items()):
            row = Deployment(
                tool_id=tool_id,
                robot_id=robot_id,
                protocol="kuka_kvp",
                target="$TOOL_DATA[3]",
                status=fields.pop("status", name),
                scope="stored",
                actor="alice",
                created_at=now - timedelta(minutes=10 - minutes),
                **fields,
            )
            session.add(row)
            session.flush()
            ids[name] = row.id
    engine_for(url).dispose()
    return ids


@pytest.fixture(scope="module")
def cell(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    tmp = tmp_path_factory.mktemp("tool-page")
    with (
        fresh_database("sqlite", tmp, None) as url,
        live_server(url, workers=1, solvers=0) as server,
        server.client() as http,
    ):
        bench = http.post("/v1/robots", json={"name": "bench", "cell": "c1"}).json()
        loose = http.post(f"/v1/robots/{bench['id']}/tools", json={"name": "loose"}).json()
        quick = http.post(
            f"/v1/robots/{bench['id']}/tools", json={"name": "quick", "slot": 2}
        ).json()
        manual = {"method": "manual", "tcp": V1}
        http.post(f"/v1/tools/{loose['id']}/calibrations", json=manual).raise_for_status()
        for z in (150.0, 150.5, 151.0):  # seconds apart, as a person retrying at the cell
            body = {"method": "manual", "tcp": {"position_mm": [0.0, 0.0, z]}}
            http.post(f"/v1/tools/{quick['id']}/calibrations", json=body).raise_for_status()
        kr16 = http.post("/v1/robots", json={"name": "kr16", "cell": "c1"}).json()
        controller = {"protocol": "kuka_kvp", "host": "127.0.0.1", "port": _closed_port(),
                      "timeout_s": 1.0}  # fmt: skip
        http.put(f"/v1/robots/{kr16['id']}/controller", json=controller).raise_for_status()
        torch = http.post(
            f"/v1/robots/{kr16['id']}/tools", json={"name": "torch", "slot": 3}
        ).json()
        for tcp in (V1, V2):
            body = {"method": "manual", "tcp": tcp}
            http.post(f"/v1/tools/{torch['id']}/calibrations", json=body).raise_for_status()
        planted = _plant_deployments(url, torch["id"], kr16["id"])
        yield Cell(server, loose["id"], quick["id"], torch["id"], planted)


@pytest.fixture(scope="module")
def console_server(cell: Cell) -> LiveServer:
    """The server the browser fixtures (tests/browser/conftest.py) let the pages reach."""
    return cell.server


# --- downloads and cards ----------------------------------------------------------------------


def test_a_tool_without_a_slot_says_why_there_is_no_ls_or_tool_cnd(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.loose}")
    for fmt, words in (
        ("fanuc", "Set the tool's slot (1-10 on FANUC) to download its TP program (.LS)"),
        ("yaskawa", "Set the tool's slot (0-63 on YASKAWA) to download its TOOL.CND"),
    ):
        card = page.locator(f"#controllers .card[data-format={fmt}]")
        expect(card.locator("pre")).to_be_visible()  # its line is there; its file is not
        expect(card.locator(".unavailable")).to_be_visible()
        expect(card.locator(".unavailable")).to_contain_text(words)
        expect(card.locator("button.download")).to_be_disabled()
    # A format that needs no number still downloads.
    ur = page.locator("#controllers .card[data-format=ur]")
    expect(ur.locator("button.download")).to_be_enabled()
    expect(ur.locator(".unavailable")).to_have_count(0)


def test_no_card_reads_none(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.loose}")
    cards = page.locator("#controllers .card")
    expect(cards).to_have_count(6)
    kuka = page.locator("#controllers .card[data-format=kuka]")
    expect(kuka).to_contain_text("$TOOL_DATA[n]; it has none: set the tool's slot")
    abb = page.locator("#controllers .card[data-format=abb]")
    expect(abb).to_contain_text("tool 'loose' has none.")
    text = page.locator("#controllers").inner_text()
    assert "None" not in text, text  # the KUKA card read "got None", the ABB one "has None"


def test_a_refused_download_says_why_in_its_card(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.loose}")
    problem = {"type": "/problems/invalid-options", "title": "Invalid options", "status": 422,
               "detail": "the file cannot be written: test refusal"}  # fmt: skip

    def refuse(route: Route) -> None:
        if "text/plain" in (route.request.headers.get("accept") or ""):
            route.fulfill(status=422, content_type="application/problem+json",
                          body=json.dumps(problem))  # fmt: skip
        else:
            route.continue_()

    page.route("**/v1/tools/*/tcp?format=ur", refuse)
    card = page.locator("#controllers .card[data-format=ur]")
    card.locator("button.download").click()
    expect(card.locator("[role=alert]")).to_contain_text("the file cannot be written: test refusal")


# --- layout -----------------------------------------------------------------------------------

#: What is wider than the window, or cut inside a box that scrolls: each as tag#id.class.
CUT_OFF = """() => {
    const width = document.documentElement.clientWidth;
    const name = (e) => `${e.tagName.toLowerCase()}#${e.id}.${e.className}`;
    const out = [];
    for (const e of document.querySelectorAll("main *")) {
        if (e.closest(".plot") && !e.classList.contains("plot")) continue; // Plotly's own
        const box = e.getBoundingClientRect();
        if (box.width === 0 || box.height === 0) continue;
        if (box.right > width + 0.5) out.push(`${name(e)} ends at ${Math.round(box.right)}`);
        const style = getComputedStyle(e);
        const scrolls = ["auto", "scroll", "hidden"].includes(style.overflowX);
        if (scrolls && e.scrollWidth > e.clientWidth + 1)
            out.push(`${name(e)} hides ${e.scrollWidth - e.clientWidth} px`);
    }
    return out;
}"""


@pytest.mark.parametrize(("width", "height"), [(1400, 900), (768, 1024)])
def test_the_tool_page_fits_the_window(page: Page, cell: Cell, width: int, height: int) -> None:
    page.set_viewport_size({"width": width, "height": height})
    sign_in_to(page, cell.server, "/ui/")
    for tool in (cell.torch, cell.loose):
        page.goto(f"{cell.server.url}/ui/tools/{tool}")  # signed in: the key is in the tab
        expect(page.locator("main")).to_have_attribute("aria-busy", "false")
        expect(page.locator("#controllers .card")).to_have_count(6)
        expect(page.locator("#plot-tcp .main-svg").first).to_be_visible()
        page.wait_for_timeout(300)  # Plotly's responsive resize
        scroll, client = page.evaluate(
            "[document.documentElement.scrollWidth, document.documentElement.clientWidth]"
        )
        assert scroll <= client, f"{scroll} px wide in a {client} px window"
        assert page.evaluate(CUT_OFF) == []
        # The plot spans the page's width, not the width it was drawn at.
        plot = page.locator("#plot-tcp .main-svg").first.bounding_box()
        assert plot is not None
        assert plot["x"] + plot["width"] <= client


# --- the TCP chart ----------------------------------------------------------------------------


def test_versions_minutes_apart_are_one_step_each(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.quick}")
    expect(page.locator("#plot-tcp .main-svg").first).to_be_visible()
    chart: dict[str, Any] = page.evaluate(
        """() => {
        const gd = document.getElementById("plot-tcp");
        const xaxis = gd._fullLayout.xaxis;
        return {
            pixels: gd.data.map((trace) => trace.x.map((x) => xaxis.d2p(x))),
            ticks: [...gd.querySelectorAll(".xtick text")].map((t) => t.textContent),
            hover: gd.data[0].customdata,
        };
    }"""
    )
    for pixels in chart["pixels"]:  # x, y and z: the same three positions
        steps = [b - a for a, b in pairwise(pixels)]
        assert len(steps) == 2
        assert min(steps) > 100, pixels  # made seconds apart, they were drawn on one spot
        assert abs(steps[0] - steps[1]) < 0.5, pixels  # one step per version
    assert chart["ticks"] == ["v1", "v2", "v3"]
    assert [label for label, _ in chart["hover"]] == ["v1", "v2", "v3"]
    assert all(any(ch.isdigit() for ch in date) for _, date in chart["hover"])  # the date


# --- deployments ------------------------------------------------------------------------------


def test_each_deployment_status_is_said_in_words(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.torch}")
    for name, deployment in cell.deployments.items():
        words = WORDS[name.removesuffix("_before")]
        row = page.locator(f"#deployments tr[data-deployment='{deployment}']")
        outcome = row.locator("td.outcome").inner_text()
        assert outcome.count(words) == 1, outcome  # said once: by the server, or by the page
    unverified = page.locator(
        f"#deployments tr[data-deployment='{cell.deployments['unverified']}']"
    )
    expect(unverified.locator(".detail")).to_have_text(
        "the controller stopped answering after $TOOL_DATA[3] was sent"
    )
    assert "not_written" not in page.locator("#deployments").inner_text()


def test_settled_and_reason_are_shown_when_the_server_sends_them(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.torch}")
    unverified = cell.deployments["unverified"]
    row = page.locator(f"#deployments tr[data-deployment='{unverified}']")
    expect(row.locator(".settled")).to_contain_text("Settled")
    expect(row.locator(".settled")).to_contain_text(
        "the controller holds what it held before (v1): v2 did not take"
    )
    expect(row.locator(".reason")).to_have_text("Why: new nozzle")
    # A row without them shows neither.
    other = page.locator(f"#deployments tr[data-deployment='{cell.deployments['mismatch']}']")
    expect(other.locator(".settled, .reason")).to_have_count(0)


def test_after_deploy_the_message_says_what_the_controller_holds(page: Page, cell: Cell) -> None:
    sign_in_to(page, cell.server, f"/ui/tools/{cell.torch}")
    page.click("#deploy-button")
    page.click("#deploy-yes")  # nothing listens at the controller's port: refused
    alert = page.locator("#deploy-outcome [role=alert]")
    expect(alert.locator(".status")).to_have_text("Not written")
    expect(alert.locator(".detail")).to_contain_text(WORDS["not_written"])  # the server's detail
    expect(alert).to_contain_text("502")

    # A write sent and not confirmed: the server's detail, whatever it says, is shown as sent.
    problem = {"type": "/problems/controller-unreachable", "title": "Controller unreachable",
               "status": 502, "detail": "the detail the server sends, as it is",
               "deployment_status": "unverified",
               "deployment_id": str(cell.deployments["unverified"])}  # fmt: skip
    page.route(
        "**/v1/tools/*/deployments",
        lambda route: (
            route.fulfill(
                status=502, content_type="application/problem+json", body=json.dumps(problem)
            )
            if route.request.method == "POST"
            else route.continue_()
        ),
    )
    page.click("#deploy-button")
    page.click("#deploy-yes")
    expect(alert.locator(".status")).to_have_text("Written, not confirmed")
    expect(alert.locator(".detail")).to_have_text("the detail the server sends, as it is")
