"""Structured logs with structlog: JSON lines for machines, readable lines on a terminal.

Every line carries the request id of the request it belongs to (app.api.middleware reads
`X-Request-ID` or makes one, echoes it, and leaves it in REQUEST_ID). Uvicorn's and the
libraries' stdlib logging goes through the same renderer, so an operator's log shipper sees
one format. Set
TCPCAL_LOG_FORMAT=json or =console to choose; by default JSON unless stderr is a terminal.
"""

from __future__ import annotations

import logging
import os
import sys
from contextvars import ContextVar
from typing import Protocol

import structlog
from structlog.typing import EventDict, Processor, WrappedLogger

LOG_FORMAT_ENV = "TCPCAL_LOG_FORMAT"
#: Set by `tcpcal serve`: each worker configures logging when it builds the app (uvicorn is
#: told to leave logging alone). Tests and embedding applications keep their own logging.
SERVING_ENV = "TCPCAL_SERVING"
#: The id of the request being served (None outside one), for every log line it causes.
REQUEST_ID: ContextVar[str | None] = ContextVar("tcpcal.request_id", default=None)
#: Where the authenticated key's name is left in the ASGI scope for the access line
#: (app.api.deps writes it, app.api.middleware reads it); never the key itself.
KEY_NAME = "tcpcal.key_name"


def _request_id(_: WrappedLogger, __: str, event: EventDict) -> EventDict:
    request_id = REQUEST_ID.get()
    if request_id is not None:
        event.setdefault("request_id", request_id)
    return event


_SHARED: list[Processor] = [
    structlog.contextvars.merge_contextvars,
    _request_id,
    structlog.stdlib.add_log_level,
    structlog.stdlib.add_logger_name,
    structlog.processors.TimeStamper(fmt="iso", utc=True),
]
# structlog always hands its events to stdlib logging: where they go (and whether at all, in
# tests and CLI commands, where nothing is configured and info lines are dropped) is decided
# by the handlers configure_logging installs.
structlog.configure(
    processors=[*_SHARED, structlog.stdlib.ProcessorFormatter.wrap_for_formatter],
    logger_factory=structlog.stdlib.LoggerFactory(),
    wrapper_class=structlog.stdlib.BoundLogger,
    cache_logger_on_first_use=True,
)


class EventLogger(Protocol):
    """What a line is written with: a structlog logger, its event and fields (the JSON a
    line carries)."""

    def info(self, event: str, *args: object, **fields: object) -> object: ...


ACCESS_LOGGER = "tcpcal.access"
EVENTS_LOGGER = "tcpcal.events"
#: The loggers written on every request: its access line, and the audit events of a write.
#: stdlib logging's until configure_logging gives each a direct one.
_direct: dict[str, EventLogger] = {
    name: structlog.stdlib.get_logger(name) for name in (ACCESS_LOGGER, EVENTS_LOGGER)
}


def access_logger() -> EventLogger:
    """The logger of the one access line per request (app.api.middleware)."""
    return _direct[ACCESS_LOGGER]


def events_logger() -> EventLogger:
    """The logger of the audit events, one line per committed write (app.services.audit.writes)."""
    return _direct[EVENTS_LOGGER]


def _named(name: str) -> Processor:
    def add_name(_: WrappedLogger, __: str, event: EventDict) -> EventDict:
        event["logger"] = name
        return event

    return add_name


def configure_logging(level: int = logging.INFO) -> None:
    """Route structlog and stdlib logging through one renderer on stderr."""
    fmt = os.environ.get(LOG_FORMAT_ENV) or ("console" if sys.stderr.isatty() else "json")
    renderer: Processor = (
        structlog.dev.ConsoleRenderer() if fmt == "console" else structlog.processors.JSONRenderer()
    )
    # The access line, written on every request, and the audit events go straight to stderr
    # with the same fields and renderer: through stdlib logging (a LogRecord, a handler, the
    # formatter's processor chain) the access line cost 125 us of CPU a request, more than
    # the rest of the hot read's middleware, and a calibration writes two events.
    sink = structlog.WriteLogger(sys.stderr)
    for name in _direct:
        _direct[name] = structlog.wrap_logger(
            sink,
            processors=[
                structlog.contextvars.merge_contextvars,
                _request_id,
                structlog.processors.add_log_level,
                _named(name),
                structlog.processors.TimeStamper(fmt="iso", utc=True),
                renderer,
            ],
            wrapper_class=structlog.make_filtering_bound_logger(level),
            cache_logger_on_first_use=True,
        )
    shared = _SHARED
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(
        structlog.stdlib.ProcessorFormatter(
            foreign_pre_chain=shared,
            processors=[
                structlog.stdlib.ProcessorFormatter.remove_processors_meta,
                structlog.processors.format_exc_info,
                renderer,
            ],
        )
    )
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)
    for name in ("uvicorn", "uvicorn.error"):
        logging.getLogger(name).handlers[:] = []
        logging.getLogger(name).propagate = True
    # One access line per request comes from app.api.middleware, with the route and key name.
    logging.getLogger("uvicorn.access").disabled = True


def get_logger(name: str) -> structlog.stdlib.BoundLogger:
    """A structlog logger; bind fields with keyword arguments: log.info("event", k=v)."""
    return structlog.stdlib.get_logger(name)
