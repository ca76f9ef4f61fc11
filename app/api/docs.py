"""/docs served offline: Swagger UI 5 (it renders OpenAPI 3.1) from the fastapi-offline
package's copy of its assets, no CDN."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from fastapi import APIRouter, FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

ASSETS = "/static/swagger-ui"
SWAGGER_UI = Path(str(files("fastapi_offline") / "static"))
router = APIRouter(include_in_schema=False)


@router.get("/docs")
def docs() -> HTMLResponse:
    """Swagger UI for the OpenAPI spec, every asset from this server."""
    return get_swagger_ui_html(
        openapi_url="/openapi.json",
        title="tcpcal API",
        swagger_js_url=f"{ASSETS}/swagger-ui-bundle.js",
        swagger_css_url=f"{ASSETS}/swagger-ui.css",
        swagger_favicon_url=f"{ASSETS}/favicon.png",
    )


def mount_assets(app: FastAPI) -> None:
    """Serve the installed Swagger UI files under ASSETS."""
    app.mount(ASSETS, StaticFiles(directory=SWAGGER_UI), name="swagger")
