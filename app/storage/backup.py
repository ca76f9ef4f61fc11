"""Consistent backups and restores of the service's database, SQLite or PostgreSQL.

SQLite: the online backup API of the sqlite3 module copies the database page by page from
one read transaction, so the copy is one consistent snapshot, the writes still in the WAL
included, while writers keep going (they wait for nothing; a copy of the file itself would
miss what is still in the WAL). The result is a plain SQLite file, checked with
`PRAGMA integrity_check` before it is reported done.

PostgreSQL: `pg_dump --format=custom` (one snapshot transaction, so consistent under writes)
and `pg_restore --clean --if-exists`; both come with the PostgreSQL client package.

Restore replaces the database's content under every server reading it, so it refuses while
another process has the database open (a running server, a publisher, a psql session), unless
forced. SQLite: every connection to a WAL database holds a shared lock on the "dead man
switch" byte of the -shm file for as long as it is open (os_unix.c, UNIX_SHM_DMS = byte 128),
so an exclusive lock on that byte that cannot be had means another process has it open.
PostgreSQL: pg_stat_activity lists the other sessions on the database.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import sqlite3
import subprocess
from pathlib import Path

from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url
from sqlalchemy.pool import NullPool

#: The byte of a WAL database's -shm file that every open connection holds a shared lock on.
_SQLITE_SHM_DMS_BYTE = 128


class BackupError(RuntimeError):
    """A backup or restore that could not be done, with the reason in words."""


def backup(database_url: str, path: Path) -> str:
    """Write a consistent copy of the database to `path`; a line saying what was done."""
    url = make_url(database_url)
    if url.get_backend_name() == "sqlite":
        source = _sqlite_file(database_url)
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(path.name + ".partial")
        partial.unlink(missing_ok=True)
        with sqlite3.connect(source) as src, sqlite3.connect(partial) as dst:
            src.backup(dst)
        _check_integrity(partial)
        partial.replace(path)
        return f"backed up {source} to {path} (SQLite online backup, integrity ok)"
    _run(["pg_dump", "--format=custom", "--file", str(path), _libpq(database_url)], "pg_dump")
    return f"backed up {url.database} to {path} (pg_dump, custom format)"


def restore(database_url: str, path: Path, *, force: bool = False) -> str:
    """Replace the database's content with a backup made by `backup`; refused while another
    process has the database open, unless `force`."""
    if not path.is_file():
        raise BackupError(f"{path} is not a file")
    url = make_url(database_url)
    in_use = None if force else in_use_by(database_url)
    if in_use:
        raise BackupError(
            f"the database is open in {in_use} (a running tcpcal server or publisher?): "
            "stop every server and process using it, then restore; --force restores anyway"
        )
    if url.get_backend_name() == "sqlite":
        _check_integrity(path)
        target = _sqlite_file(database_url)
        with sqlite3.connect(path) as src, sqlite3.connect(target) as dst:
            src.backup(dst)
        return f"restored {target} from {path}"
    dbname = _libpq(database_url)
    _run(
        ["pg_restore", "--clean", "--if-exists", "--no-owner", "--dbname", dbname, str(path)],
        "pg_restore",
    )
    return f"restored {url.database} from {path}"


def in_use_by(database_url: str) -> str | None:
    """Who else has the database open, in words, or None when nobody does."""
    if make_url(database_url).get_backend_name() == "sqlite":
        return _sqlite_in_use(_sqlite_file(database_url))
    engine = create_engine(database_url, poolclass=NullPool)
    try:
        with engine.connect() as conn:
            others = conn.execute(
                text(
                    "SELECT count(*) FROM pg_stat_activity "
                    "WHERE datname = current_database() AND pid <> pg_backend_pid()"
                )
            ).scalar_one()
    finally:
        engine.dispose()
    return f"{others} other session(s)" if others else None


def _sqlite_in_use(database: str) -> str | None:
    shm = Path(database + "-shm")
    if not shm.is_file():
        return None  # no connection has the WAL index mapped
    fd = os.open(shm, os.O_RDWR)
    try:
        fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB, 1, _SQLITE_SHM_DMS_BYTE, os.SEEK_SET)
    except OSError:
        return "another process"
    else:
        fcntl.lockf(fd, fcntl.LOCK_UN, 1, _SQLITE_SHM_DMS_BYTE, os.SEEK_SET)
        return None
    finally:
        os.close(fd)


def _sqlite_file(database_url: str) -> str:
    database = make_url(database_url).database
    if not database or database == ":memory:":
        raise BackupError("an in-memory SQLite database has nothing to back up")
    if not Path(database).is_file():
        raise BackupError(f"no SQLite database at {database}")
    return database


def _check_integrity(path: Path) -> None:
    with sqlite3.connect(path) as conn:
        verdict = conn.execute("PRAGMA integrity_check").fetchone()[0]
    if verdict != "ok":
        raise BackupError(f"{path} fails PRAGMA integrity_check: {verdict}")


def _libpq(database_url: str) -> str:
    """The SQLAlchemy URL as libpq understands it (no driver suffix)."""
    url = make_url(database_url).set(drivername="postgresql")
    return url.render_as_string(hide_password=False)


def _run(command: list[str], tool: str) -> None:
    if shutil.which(tool) is None:
        raise BackupError(f"{tool} is not installed: install the PostgreSQL client tools")
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise BackupError(f"{tool} failed: {done.stderr.strip()}")
