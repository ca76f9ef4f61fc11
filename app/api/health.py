"""Liveness, readiness (database reachable and migrated to head) and metrics."""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import JSONResponse, PlainTextResponse, Response
from sqlalchemy.exc import SQLAlchemyError

from app.db import get_engine
from app.deps import ReadKey
from app.fleet_metrics import FLEET
from app.metrics import render
from app.migrate import current_revision, head_revision

router = APIRouter(tags=["operations"])


@router.get("/health")
def health() -> dict[str, str]:
    """Liveness: the process answers. No key needed."""
    return {"status": "ok"}


@router.get("/ready", responses={503: {"description": "not ready"}})
def ready() -> JSONResponse:
    """Readiness: the database answers and its migrations are at head (503 otherwise). No key
    needed."""
    head = head_revision()
    try:
        current = current_revision(get_engine())
    except SQLAlchemyError as exc:
        return JSONResponse(
            {"ready": False, "database": "unreachable", "detail": type(exc).__name__},
            status_code=503,
        )
    at_head = current == head
    body = {"ready": at_head, "database": "reachable", "revision": current, "head": head}
    return JSONResponse(body, status_code=200 if at_head else 503)


@router.get("/metrics", response_class=PlainTextResponse)
def metrics(key: ReadKey) -> Response:
    """Prometheus text of the whole server (every worker) and of the fleet's state (read from
    the database at each scrape); scrape with a read key (bearer token): only /health and
    /ready are open without one."""
    body, content_type = render(FLEET)
    return Response(body, media_type=content_type)
