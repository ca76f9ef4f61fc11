"""Alembic from code: upgrade, downgrade, and "is the database at head?" for /ready.

Alembic (and Mako, which it brings) is imported by the function that uses it, not with this
module: every process that imports app.main imports this one, and a server worker needs alembic
only when asked /ready (or at start, to install a bootstrap key).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from sqlalchemy import Engine

if TYPE_CHECKING:
    from alembic.config import Config

REPO_ROOT = Path(__file__).resolve().parents[2]


def alembic_config(database_url: str | None = None) -> Config:
    """Alembic config pointing at migrations/ (found beside the app package or in the cwd)."""
    from alembic.config import Config

    for base in (Path.cwd(), REPO_ROOT):
        ini = base / "alembic.ini"
        if ini.is_file():
            config = Config(str(ini))
            config.set_main_option("script_location", str(base / "migrations"))
            break
    else:
        raise FileNotFoundError("alembic.ini not found in the working directory or the repo")
    if database_url:
        config.set_main_option("sqlalchemy.url", database_url.replace("%", "%%"))
    return config


def upgrade(database_url: str | None = None, revision: str = "head") -> None:
    """Migrate the database to `revision`."""
    from alembic import command

    command.upgrade(alembic_config(database_url), revision)


def downgrade(database_url: str | None = None, revision: str = "base") -> None:
    """Migrate the database down to `revision`."""
    from alembic import command

    command.downgrade(alembic_config(database_url), revision)


def head_revision() -> str | None:
    """The newest revision in migrations/."""
    from alembic.script import ScriptDirectory

    return ScriptDirectory.from_config(alembic_config()).get_current_head()


def current_revision(engine: Engine) -> str | None:
    """The revision the database is at (None when never migrated)."""
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


def database_not_ready(url: str) -> str | None:
    """Why the database at `url` cannot serve a command that reads or writes it, in one
    sentence that names the database and how to point at the right one; None when it can.

    A SQLite file that does not exist is never created here: a command run outside the
    project directory would otherwise make an empty database beside it and fail on its first
    table (the default URL is relative to the working directory)."""
    from sqlalchemy import create_engine
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import SQLAlchemyError

    parsed = make_url(url)
    shown = parsed.render_as_string(hide_password=True)
    point = (
        "run it in the directory the server runs in, or set TCPCAL_DATABASE_URL to the "
        "server's database (the same value the server has)"
    )
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database or ""
        if database and database != ":memory:" and not database.startswith("file:"):
            path = Path(database).resolve()
            if not path.is_file():
                return (
                    f"no tcpcal database at {path} ({shown}, relative to this directory): {point}"
                )
    engine = create_engine(url)
    try:
        revision = current_revision(engine)
    except SQLAlchemyError as exc:
        cause = exc.__cause__ or exc
        reason = str(cause).splitlines()[0]
        return f"cannot open the database {shown} ({reason}): {point}"
    finally:
        engine.dispose()
    if revision is None:
        return (
            f"the database {shown} has no tcpcal tables: migrate it with `tcpcal db upgrade`, "
            f"or {point}"
        )
    return None
