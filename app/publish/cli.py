"""`tcpcal publish`: configuration checked, signals wired, the runner started.

The configuration is checked before the database and the outbox's services (numpy, scipy:
about 2 s) are imported, so that a typo in it is reported at once.
"""

from __future__ import annotations

import logging
import signal
import sys
import threading
from types import FrameType

from pydantic import ValidationError

from app.publish.settings import PublishSettings
from app.publish.sink import SinkError
from app.publish.sinks import build_sinks

log = logging.getLogger(__name__)

#: Exit codes: a configuration or start-up failure, and a fleet lock lost while running.
EXIT_CONFIG = 2
EXIT_LOCK_LOST = 3


def _fail(message: str, code: int = EXIT_CONFIG) -> int:
    print(f"tcpcal publish: {message}", file=sys.stderr, flush=True)
    return code


def run_publisher() -> int:
    """Run until SIGTERM/SIGINT; the process's exit code."""
    try:
        settings = PublishSettings()
        sinks = build_sinks(settings)
    except ValidationError as exc:
        return _fail(f"bad configuration: {exc}")
    except SinkError as exc:
        return _fail(str(exc))
    from sqlalchemy.exc import SQLAlchemyError

    from app.publish.runner import LockLost, Runner
    from app.storage.db import get_engine
    from app.storage.migrate import current_revision, head_revision

    engine = get_engine()
    try:
        current = current_revision(engine)
    except SQLAlchemyError as exc:
        return _fail(f"cannot read the database ({type(exc).__name__}): {exc}")
    if current != head_revision():
        return _fail(
            f"the database is at revision {current}, not {head_revision()}: run tcpcal db upgrade"
        )
    stopping = threading.Event()

    def stop(signum: int, _: FrameType | None) -> None:
        log.info("stopping on signal %s", signum)
        stopping.set()

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    runner = Runner(
        engine,
        sinks,
        stopping,
        batch=settings.publish_batch,
        poll_s=settings.publish_poll_s,
        keep_s=settings.outbox_keep_s,
    )
    try:
        runner.run()
    except LockLost as exc:
        return _fail(f"{exc}; exiting so that a supervisor restarts the publisher", EXIT_LOCK_LOST)
    except SinkError as exc:
        return _fail(str(exc))
    finally:
        engine.dispose()
    log.info("stopped after delivering %d outbox rows", runner.delivered)
    return 0
