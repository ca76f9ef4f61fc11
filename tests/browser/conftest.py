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

import pytest
from playwright.sync_api import Browser, Playwright, sync_playwright

CHROMIUM = os.environ.get("TCPCAL_CHROMIUM", "/usr/bin/chromium")
#: Headless Chromium draws WebGL (Plotly's 3-D view) with its software renderer.
CHROMIUM_ARGS = ["--enable-unsafe-swiftshader", "--use-angle=swiftshader"]


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
