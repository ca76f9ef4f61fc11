"""The ASGI app: create_app() wires routers, middleware, error handlers and start-up."""

from __future__ import annotations

import gc
import logging
import os
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI
from fastapi.routing import APIRoute
from sqlalchemy.exc import SQLAlchemyError

from app import __version__
from app.api import (
    audit,
    calibrations,
    checks,
    console,
    controllers,
    deployments,
    docs,
    fleet,
    formats,
    frame_checks,
    frames,
    health,
    keys,
    methods,
    references,
    robots,
    sessions,
    solve,
    tools,
    versions,
)
from app.api.middleware import BodyLimitMiddleware, HeadAsGetMiddleware, RequestLogMiddleware
from app.api.openapi import build_openapi
from app.api.problems import install_error_handlers
from app.config import get_settings
from app.logs import SERVING_ENV, configure_logging
from app.security.auth import ensure_bootstrap_key
from app.services import solve_pool
from app.services.controllers import watcher
from app.storage.db import get_engine, session_scope
from app.storage.migrate import current_revision, head_revision

log = logging.getLogger("tcpcal")
#: What each solver process imports as it starts: the solve path of the calibrations and of
#: /v1/solve (numpy, scipy, the methods), and scipy.optimize, which the fits import when they
#: first run (app.solvers.plane.search): a server worker does not import it at start.
SOLVER_PRELOAD = (
    "app.services.calibrations.writes",
    "app.services.calibrations.detached",
    "scipy.optimize",
)


def settle_heap() -> None:
    """Leave the objects made at start-up (modules, the app, numpy and scipy) out of every
    later garbage collection: a full collection walked all of them, a pause of tens of
    milliseconds at random that showed as the p99 of every route under load."""
    gc.collect()
    gc.freeze()


def _operation_id(route: APIRoute) -> str:
    return route.name


def _bootstrap() -> None:
    settings = get_settings()
    if settings.bootstrap_admin_key is None:
        return
    try:
        if current_revision(get_engine()) != head_revision():
            log.warning(
                "database is not migrated to head; bootstrap key not installed "
                "(run `tcpcal db upgrade`)"
            )
            return
        with session_scope(write=True) as session:
            ensure_bootstrap_key(session, settings.bootstrap_admin_key.get_secret_value())
    except SQLAlchemyError:
        log.exception("could not install the bootstrap admin key")


@asynccontextmanager
async def lifespan(_: FastAPI) -> AsyncIterator[None]:
    _bootstrap()
    if os.environ.get(SERVING_ENV):  # a server (not a test's app): start solvers up front
        solve_pool.start(preload=SOLVER_PRELOAD)
        settle_heap()
    interval = get_settings().reconcile_interval_s
    if interval > 0:
        watcher.start_watcher(interval)
    try:
        yield
    finally:
        watcher.stop_watcher()
        solve_pool.stop()


def create_app() -> FastAPI:
    """A new tcpcal application."""
    settings = get_settings()
    if os.environ.get(SERVING_ENV):  # set by `tcpcal serve` for every worker it starts
        configure_logging()
    app = FastAPI(
        title="tcpcal",
        version=__version__,
        summary="Tool Center Point calibration as a fleet service",
        lifespan=lifespan,
        generate_unique_id_function=_operation_id,
        docs_url=None,  # app.api.docs serves /docs from the installed Swagger UI, offline
        redoc_url=None,  # ReDoc would load its script from a CDN
    )
    install_error_handlers(app)
    # Routes are matched in order, each router's after the last: the paths cell controllers
    # poll come first, then the submissions that test clients send by the hundred.
    routers = (
        versions,
        calibrations,
        solve,
        health,
        keys,
        robots,
        tools,
        frames,
        frame_checks,
        references,
        checks,
        methods,
        formats,
        fleet,
        sessions,
        controllers,
        deployments,
        audit,
        docs,
        console,
    )
    for module in routers:
        app.include_router(module.router)
    docs.mount_assets(app)
    console.mount_assets(app)
    app.add_middleware(HeadAsGetMiddleware)
    app.add_middleware(BodyLimitMiddleware, max_bytes=settings.max_body_bytes)
    # Outermost: every log line of the request, the access line included, has its id.
    app.add_middleware(RequestLogMiddleware)
    app.openapi = lambda: build_openapi(app)  # type: ignore[method-assign]
    return app


app = create_app()
