"""The web console: `/` redirects to `/ui/`; every console page is one HTML shell whose script
(app/console/console.js) reads the JSON API with the key the person signed in with.

Offline by construction: the shell, script and stylesheet come from app/console, Plotly from
the installed `plotly` package's own copy of plotly.min.js, and the Content-Security-Policy
forbids every other host, so a page that tried to reach one would fail in the browser.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from fastapi import APIRouter, FastAPI
from fastapi.responses import FileResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles

CONSOLE = Path(__file__).resolve().parents[1] / "console"
PLOTLY_JS = Path(str(files("plotly") / "package_data" / "plotly.min.js"))
ASSETS = "/ui/assets"

#: Only this server: scripts, styles (Plotly sets inline styles), images, API calls.
CSP = (
    "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data: blob:; connect-src 'self'; object-src 'none'; base-uri 'none'; "
    "form-action 'self'; frame-ancestors 'none'"
)
HEADERS = {"Content-Security-Policy": CSP, "Cache-Control": "no-cache"}

router = APIRouter(include_in_schema=False)


@router.get("/")
def root() -> RedirectResponse:
    """The console is the front door."""
    return RedirectResponse("/ui/", status_code=307)


def _shell() -> FileResponse:
    return FileResponse(CONSOLE / "index.html", media_type="text/html", headers=HEADERS)


@router.get("/ui/")
def fleet_page() -> FileResponse:
    """Every tool of the fleet."""
    return _shell()


@router.get("/ui/tools/{tool_id}")
def tool_page(tool_id: str) -> FileResponse:
    """One tool: versions, activations, drift, checks, controller text."""
    return _shell()


@router.get("/ui/tools/{tool_id}/calibrate")
def calibrate_page(tool_id: str) -> FileResponse:
    """A guided calibration at the cell: capture or type touches, finish, activate, deploy."""
    return _shell()


@router.get("/ui/frames/{frame_id}/calibrate")
def frame_calibrate_page(frame_id: str) -> FileResponse:
    """A frame taught at the cell: a guided frame session, its touches and axes in 3-D."""
    return _shell()


@router.get("/ui/calibrations/{calibration_id}")
def report_page(calibration_id: str) -> FileResponse:
    """One calibration's report."""
    return _shell()


@router.get("/ui/vendor/plotly.min.js")
def plotly_js() -> FileResponse:
    """Plotly from the installed package (versioned with it, so cacheable for a day)."""
    return FileResponse(
        PLOTLY_JS, media_type="text/javascript", headers={"Cache-Control": "max-age=86400"}
    )


def mount_assets(app: FastAPI) -> None:
    """Serve the console's script and stylesheet under ASSETS."""
    app.mount(ASSETS, StaticFiles(directory=CONSOLE, html=False), name="console")
