"""Liveness, readiness (database reachable and migrated to head) and metrics."""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import JSONResponse, PlainTextResponse, Response

from app.api.deps import ReadKey
from app.metrics import render
from app.services import readiness
from app.services.controllers.watcher import watcher_document
from app.services.fleet.collector import FLEET

router = APIRouter(tags=["operations"])


@router.get("/health")
def health() -> dict[str, str]:
    """Liveness: the process answers. No key needed."""
    return {"status": "ok"}


@router.get("/ready", responses={503: {"description": "not ready"}})
def ready() -> JSONResponse:
    """Readiness: the database answers and its migrations are at head (503 otherwise), and
    the state of this process's controller watcher. No key needed."""
    state = readiness.database_state()
    if state.unreachable is not None:
        return JSONResponse(
            {"ready": False, "database": "unreachable", "detail": state.unreachable},
            status_code=503,
        )
    body = {
        "ready": state.at_head,
        "database": "reachable",
        "revision": state.revision,
        "head": state.head,
        "watcher": watcher_document(),
    }
    return JSONResponse(body, status_code=200 if state.at_head else 503)


@router.get("/metrics", response_class=PlainTextResponse)
def metrics(key: ReadKey) -> Response:
    """Prometheus text of the whole server (every worker) and of the fleet's state (read from
    the database at each scrape); scrape with a read key (bearer token): only /health and
    /ready are open without one."""
    body, content_type = render(FLEET)
    return Response(body, media_type=content_type)
