"""The `tcpcal` command: serve, migrate, manage keys, write the OpenAPI spec, talk to a server.

The commands that talk to a server are this package's modules: client (tools, calibrate,
history, activate, rollback, check, export, audit), controllers (deploy, reconcile),
guided (calibrate --guided), recheck (check --capture), all over http (the one HTTP
client and its exit codes), reading the bodies typed in bodies; demo fills `tcpcal demo`'s
fleet.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from app.cli import http as client_http
from app.cli.client import register as register_client
from app.cli.connection import register as register_connection_commands
from app.cli.controllers import register as register_controller_commands
from app.cli.frame_check import register as register_frame_check
from app.cli.frames import register as register_frame_commands

if TYPE_CHECKING:
    import httpx

    from app.security.auth import Principal

cli = typer.Typer(help="tcpcal: Tool Center Point calibration service.", no_args_is_help=True)
db_cli = typer.Typer(help="Database migrations.", no_args_is_help=True)
keys_cli = typer.Typer(help="API keys (writes the database directly).", no_args_is_help=True)
client_cli = typer.Typer(help="Talk to a running server over HTTP.", no_args_is_help=True)
cli.add_typer(db_cli, name="db")
cli.add_typer(keys_cli, name="keys")
cli.add_typer(client_cli, name="client")

OPENAPI_PATH = Path("openapi") / "openapi.json"
KeyId = Annotated[str, typer.Argument(help="the key's id (tcpcal keys list)")]


@cli.command()
def serve(
    host: Annotated[str, typer.Option(help="interface to bind")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port")] = 8000,
    workers: Annotated[int, typer.Option(min=1, help="worker processes")] = 1,
) -> None:
    """Serve the API with uvicorn (migrate first: `tcpcal db upgrade`)."""
    import uvicorn

    _fresh_metrics_directory()
    from app.logs import SERVING_ENV
    from app.server import HTTP_PROTOCOL

    os.environ[SERVING_ENV] = "1"  # each worker sets up structured logging (app.logs)

    uvicorn.run(
        "app.main:app",
        host=host,
        port=port,
        workers=workers,
        proxy_headers=True,
        http=HTTP_PROTOCOL,
        log_config=None,
        access_log=False,
    )


def _fresh_metrics_directory() -> None:
    """Point prometheus-client's multiprocess mode at an empty directory before any worker
    imports it, so that /metrics adds up every worker (app.metrics). An operator may choose
    the directory with PROMETHEUS_MULTIPROC_DIR; its old samples are removed at start."""
    import tempfile

    directory = os.environ.get("PROMETHEUS_MULTIPROC_DIR")
    if directory:
        Path(directory).mkdir(parents=True, exist_ok=True)
        for stale in Path(directory).glob("*.db"):
            stale.unlink()
    else:
        import atexit
        import shutil

        created = tempfile.mkdtemp(prefix="tcpcal-metrics-")
        os.environ["PROMETHEUS_MULTIPROC_DIR"] = created
        atexit.register(shutil.rmtree, created, ignore_errors=True)


@cli.command()
def publish() -> None:
    """Publish every committed change to the plant (MQTT: TCPCAL_MQTT_URL, TCPCAL_MQTT_PREFIX,
    TCPCAL_MQTT_COMMANDS=true to answer re-check commands; OPC UA: TCPCAL_OPCUA_ENDPOINT,
    TCPCAL_OPCUA_ANONYMOUS) from the database's outbox: one publisher per fleet, a second one
    waits. Stops on SIGTERM. Exits 2 with a message when the configuration is wrong or the
    broker cannot be reached at start-up."""
    from app.logs import configure_logging
    from app.publish.cli import run_publisher

    configure_logging()
    code = run_publisher()
    # Everything is closed (sinks, fleet lock, database connections): leave without the
    # interpreter's teardown of numpy, scipy and the rest, which took 1.7 s on a loaded
    # machine and would break the promise to stop within a second of SIGTERM.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


@db_cli.command("upgrade")
def db_upgrade(revision: str = "head") -> None:
    """Migrate the database (TCPCAL_DATABASE_URL) to a revision, head by default."""
    from app.config import get_settings
    from app.storage.migrate import upgrade

    upgrade(get_settings().database_url, revision)
    typer.echo(f"database at {revision}")


@db_cli.command("downgrade")
def db_downgrade(revision: str) -> None:
    """Migrate the database down to a revision ("base" empties it)."""
    from app.config import get_settings
    from app.storage.migrate import downgrade

    downgrade(get_settings().database_url, revision)
    typer.echo(f"database at {revision}")


@db_cli.command("current")
def db_current() -> None:
    """Print the database's revision and the newest one available."""
    from app.storage.db import get_engine
    from app.storage.migrate import current_revision, head_revision

    typer.echo(f"current: {current_revision(get_engine())}  head: {head_revision()}")


@cli.command()
def demo() -> None:
    """Migrate the database (TCPCAL_DATABASE_URL) and fill it, if empty, with a small
    realistic fleet and 14 months of calibrations and checks."""
    from app.cli.demo import FleetNotEmpty, fill
    from app.config import get_settings
    from app.storage.db import session_scope
    from app.storage.migrate import upgrade

    upgrade(get_settings().database_url)
    try:
        with session_scope(write=True) as session:
            counts = fill(session)
    except FleetNotEmpty as exc:
        typer.echo(f"{exc}; point TCPCAL_DATABASE_URL at a new database", err=True)
        raise typer.Exit(4) from None
    made = ", ".join(f"{n} {what}" for what, n in counts.items())
    typer.echo(f"demo fleet written: {made}")
    # The key must go into the database just filled, not the default one.
    url = get_settings().database_url
    tcpcal = Path(sys.executable).parent / "tcpcal"  # this venv's, on PATH or not
    typer.echo(
        "sign in to the console with a key of this database:\n"
        f"  TCPCAL_DATABASE_URL={url} {tcpcal} keys create --scope admin --name me"
    )


@keys_cli.command("create")
def keys_create(
    scope: Annotated[str, typer.Option(help="read | calibrate | admin")],
    name: Annotated[str, typer.Option(help="who holds the key, e.g. cell-12")],
    cells: Annotated[
        list[str] | None,
        typer.Option(
            "--cells",
            help="limit the key to the robots of this cell (repeat, or comma-separate, for "
            "several); leave out for every cell",
        ),
    ] = None,
) -> None:
    """Create an API key and print it (shown once; only its hash is stored)."""
    from pydantic import ValidationError

    from app.schemas.keys import KeyCreate
    from app.scopes import SCOPES
    from app.services.keys import create_key
    from app.storage.db import session_scope

    if scope not in SCOPES:
        typer.echo(f"scope must be one of {', '.join(SCOPES)}", err=True)
        raise typer.Exit(2)
    names = None if not cells else [c.strip() for arg in cells for c in arg.split(",")]
    try:  # the checks POST /v1/keys makes: names of cells, non-empty
        checked = KeyCreate.model_validate({"name": name, "scope": scope, "cells": names})
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        typer.echo(f"error: {where}: {first['msg']}", err=True)
        raise typer.Exit(2) from None
    _database_or_exit()
    with session_scope(write=True) as session:
        row, secret = create_key(
            session, name=name, scope=checked.scope, cells=names, actor=_cli_principal()
        )
        key_id = row.id
    limited = f"\ncells: {', '.join(names)}" if names else ""
    typer.echo(f"id:    {key_id}\nscope: {scope}{limited}\nkey:   {secret}")


@keys_cli.command("list")
def keys_list() -> None:
    """List keys (never their secrets)."""
    from app.services.keys import list_keys
    from app.storage.db import session_scope
    from app.storage.models import ApiKey

    _database_or_exit()
    with session_scope(write=False) as session:
        cursor = None
        rows: list[ApiKey] = []
        while True:
            page, cursor = list_keys(session, limit=500, cursor=cursor)
            rows += page
            if cursor is None:
                break
        for row in rows:
            state = "revoked" if row.revoked_at else "active"
            cells = f"  cells {','.join(row.cells)}" if row.cells else ""
            typer.echo(f"{row.id}  {row.scope:<9}  {state:<7}  {row.prefix}...  {row.name}{cells}")


@keys_cli.command("revoke")
def keys_revoke(
    key_id: Annotated[str, typer.Argument(help="the key's id (tcpcal keys list)")],
) -> None:
    """Revoke a key: it answers 401 from now on, on every worker and instance."""
    from app.errors import DomainError
    from app.services.keys import revoke_key
    from app.storage.db import session_scope

    _database_or_exit()
    try:
        with session_scope(write=True) as session:
            revoke_key(session, key_id=key_id, actor=_cli_principal())
    except DomainError as exc:
        typer.echo(f"error: {exc.detail}", err=True)
        raise typer.Exit(1) from exc
    typer.echo(f"revoked {key_id}")


@keys_cli.command("rotate")
def keys_rotate(
    key_id: Annotated[str, typer.Argument(help="the key's id (tcpcal keys list)")],
) -> None:
    """Replace a key by a new one of the same name and scope; print the new key once."""
    from app.errors import DomainError
    from app.services.keys import rotate_key
    from app.storage.db import session_scope

    _database_or_exit()
    try:
        with session_scope(write=True) as session:
            row, secret = rotate_key(session, key_id=key_id, actor=_cli_principal())
            new_id, scope = row.id, row.scope
    except DomainError as exc:
        typer.echo(f"error: {exc.detail}", err=True)
        raise typer.Exit(1) from exc
    typer.echo(f"revoked {key_id}\nid:    {new_id}\nscope: {scope}\nkey:   {secret}")


def _database_or_exit() -> None:
    """Exit 2 with one sentence when the configured database is not a tcpcal database (a
    command run outside the project directory, or never migrated): never create one."""
    from app.config import get_settings
    from app.storage.migrate import database_not_ready

    problem = database_not_ready(get_settings().database_url)
    if problem is not None:
        typer.echo(f"error: {problem}", err=True)
        raise typer.Exit(2)


def _cli_principal() -> Principal:
    """Who acts from the command line, as the audit trail records it."""
    import getpass

    from app.security.auth import Principal

    return Principal(key_id="cli", name=f"cli:{getpass.getuser()}", scope="admin")


@db_cli.command("backup")
def db_backup(
    path: Annotated[Path, typer.Argument(help="file to write (SQLite file or pg_dump archive)")],
) -> None:
    """Write a consistent backup of the database while the servers keep running."""
    from app.config import get_settings
    from app.storage.backup import BackupError, backup

    try:
        typer.echo(backup(get_settings().database_url, path))
    except BackupError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(1) from exc


@db_cli.command("restore")
def db_restore(
    path: Annotated[Path, typer.Argument(help="a backup written by `tcpcal db backup`")],
    force: Annotated[
        bool, typer.Option(help="restore even while other processes have the database open")
    ] = False,
) -> None:
    """Replace the database's content with a backup; refused while a server (or any other
    process) has the database open: stop them first."""
    from app.config import get_settings
    from app.storage.backup import BackupError, restore

    try:
        typer.echo(restore(get_settings().database_url, path, force=force))
    except BackupError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(1) from exc


@cli.command()
def openapi(
    out: Annotated[Path, typer.Option(help="where to write the spec")] = OPENAPI_PATH,
    check: Annotated[bool, typer.Option(help="exit 1 if the file differs")] = False,
) -> None:
    """Write (or --check) the committed OpenAPI spec from the app."""
    from app.api.openapi import openapi_text
    from app.main import create_app

    text = openapi_text(create_app())
    if check:
        if not out.is_file() or out.read_text() != text:
            typer.echo(f"{out} is stale; run `tcpcal openapi`", err=True)
            raise typer.Exit(1)
        typer.echo(f"{out} is up to date")
        return
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    typer.echo(f"wrote {out}")


def _print_response(response: httpx.Response) -> None:
    typer.echo(json.dumps(response.json(), indent=2) if response.content else "")
    if response.status_code >= 400:
        raise typer.Exit(1)


@client_cli.command("get")
def client_get(path: str) -> None:
    """GET a path, e.g. /v1/tools/<id>/tcp?format=<a format of /v1/formats>."""
    _print_response(client_http.request("GET", path))


@client_cli.command("post")
def client_post(
    path: str,
    body: Annotated[Path, typer.Argument(help="JSON file, or - for standard input")],
) -> None:
    """POST a JSON body, e.g. a calibration submission."""
    payload = json.load(sys.stdin) if str(body) == "-" else json.loads(body.read_text())
    _print_response(client_http.request("POST", path, json=payload))


def main() -> None:
    """Console-script entry point."""
    cli()


register_client(cli)
register_controller_commands(cli)
register_connection_commands(cli)
register_frame_commands(cli)
register_frame_check(cli)
