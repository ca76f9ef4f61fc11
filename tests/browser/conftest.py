"""A real Chromium (Debian's /usr/bin/chromium) driven by Playwright, against a live server.

Without the browser the console tests are skipped on a developer's machine, and fail under CI
(`CI` or `TCPCAL_REQUIRE_BROWSER` set; `.ci/run` installs chromium): a missing browser must
never pass a CI run silently.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from playwright.sync_api import (
    Browser,
    BrowserContext,
    Page,
    Playwright,
    Request,
    expect,
    sync_playwright,
)

from testbed.live_server import LiveServer

CHROMIUM = os.environ.get("TCPCAL_CHROMIUM", "/usr/bin/chromium")
#: Headless Chromium draws WebGL (Plotly's 3-D view) with its software renderer (SwiftShader),
#: and composites pages in software: compositing through SwiftShader as well cost a third more
#: of Chromium's CPU per page (sign-in and a report: 6.6-7.8 -> 5.2-5.9 CPU-s on a slow 2-core
#: machine), and the suite is short of CPU. Every host but the server's loopback address
#: resolves to nothing, so a CDN the console reached for could not answer it; the `context`
#: fixture records each such request and fails the test.
CHROMIUM_ARGS = [
    "--enable-unsafe-swiftshader",
    "--use-angle=swiftshader",
    "--disable-gpu-compositing",
    "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
]


def chromium_path() -> str | None:
    """The Chromium executable, or None when this machine has none."""
    if Path(CHROMIUM).is_file():
        return CHROMIUM
    return shutil.which("chromium")


def browser_required() -> bool:
    return bool(os.environ.get("CI") or os.environ.get("TCPCAL_REQUIRE_BROWSER"))


@pytest.fixture(scope="session")
def playwright() -> Iterator[Playwright]:
    with sync_playwright() as pw:
        yield pw


@pytest.fixture(scope="session")
def browser(playwright: Playwright) -> Iterator[Browser]:
    executable = chromium_path()
    if executable is None:
        message = f"no Chromium at {CHROMIUM}: apt-get install chromium (.ci/run does)"
        if browser_required():
            pytest.fail(message)
        pytest.skip(message)
    browser = playwright.chromium.launch(executable_path=executable, args=CHROMIUM_ARGS)
    yield browser
    browser.close()


@pytest.fixture
def context(browser: Browser, console_server: LiveServer) -> Iterator[BrowserContext]:
    """A fresh browser profile that records every request to another host (which cannot be
    answered: CHROMIUM_ARGS resolve no host name) and fails the test if there was one.

    Requests are watched, not intercepted: routing every request through Playwright (its
    `route`) turns the HTTP cache off and cost a fifth more of Chromium's CPU per page."""
    ctx = browser.new_context(viewport={"width": 1400, "height": 1000}, accept_downloads=True)
    own = urlsplit(console_server.url).netloc
    elsewhere: list[str] = []

    def watch(request: Request) -> None:
        url = request.url
        if urlsplit(url).netloc != own and not url.startswith(("data:", "blob:")):
            elsewhere.append(url)

    ctx.on("request", watch)
    yield ctx
    ctx.close()
    assert elsewhere == [], f"the console reached for other hosts: {elsewhere}"


@pytest.fixture
def page(context: BrowserContext) -> Iterator[Page]:
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    yield page
    assert errors == [], f"script errors on the page: {errors}"


def sign_in_to(page: Page, server: LiveServer, path: str = "/", key: str | None = None) -> None:
    """Open `path` on the console, sign in (the server's admin key unless `key` is given) and
    wait until the page is drawn whole: main stops being aria-busy after the last plot and
    table, so a click cannot land where a late plot has just moved a button."""
    page.goto(server.url + path)
    page.fill("input[name=api_key]", key or server.admin_key)
    page.click("#sign-in button[type=submit]")
    expect(page.locator("main")).to_have_attribute("aria-busy", "false")


def confirm(page: Page, reason: str) -> None:
    """Answer the console's confirmation of a write: type the reason, press its confirm
    button."""
    dialog = page.locator("dialog#confirm")
    expect(dialog).to_be_visible()
    dialog.locator("textarea[name=reason]").fill(reason)
    dialog.locator("button[type=submit]").click()
    expect(dialog).to_have_count(0)
