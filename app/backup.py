"""Consistent backups and restores of the service's database, SQLite or PostgreSQL.

SQLite: the online backup API of the sqlite3 module copies the database page by page from
one read transaction, so the copy is one consistent snapshot, the writes still in the WAL
included, while writers keep going (they wait for nothing; a copy of the file itself would
miss what is still in the WAL). The result is a plain SQLite file, checked with
`PRAGMA integrity_check` before it is reported done.

PostgreSQL: `pg_dump --format=custom` (one snapshot transaction, so consistent under writes)
and `pg_restore --clean --if-exists`; both come with the PostgreSQL client package.

Restore replaces the database's content: stop the servers first.
"""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
from pathlib import Path

from sqlalchemy.engine import make_url


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


def restore(database_url: str, path: Path) -> str:
    """Replace the database's content with a backup made by `backup`."""
    if not path.is_file():
        raise BackupError(f"{path} is not a file")
    url = make_url(database_url)
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
