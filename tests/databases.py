"""Throwaway databases for tests: a SQLite file, or a PostgreSQL database of its own.

PostgreSQL tests never touch the server's `test` database itself: each gets a fresh database
created through it and dropped (with its connections) afterwards.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url


@contextmanager
def fresh_database(
    backend: str, tmp: Path, pg_url: str | None, *, prefix: str = "tcpcal"
) -> Iterator[str]:
    """The URL of an empty database of `backend` ("sqlite" or "postgresql"), dropped after."""
    if backend == "sqlite":
        yield f"sqlite:///{tmp / f'{prefix}-{uuid.uuid4().hex[:8]}.sqlite3'}"
        return
    assert pg_url, "TCPCAL_TEST_DATABASE_URL is not set"
    admin = create_engine(pg_url, isolation_level="AUTOCOMMIT")
    name = f"{prefix}_{uuid.uuid4().hex[:10]}"
    with admin.connect() as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
        # A throwaway database need not wait for its WAL to reach the disk at each commit.
        conn.execute(text(f'ALTER DATABASE "{name}" SET synchronous_commit = off'))
    try:
        yield make_url(pg_url).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()
