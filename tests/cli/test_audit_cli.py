"""`tcpcal audit` (a table: when, who, what, which tool and version, why; the filters as
options) and `tcpcal keys create --cells`, through typer's runner; the client's HTTP goes to
the app in process."""

from __future__ import annotations

import warnings
from typing import Any

import pytest
from rich.console import Console
from typer.testing import CliRunner

from app.cli import cli
from app.cli.client import audit_why
from tests.conftest import Api, Database


@pytest.fixture
def run(api: Api, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    """The CLI with its client's requests sent to the app (an admin key)."""
    from app.cli import client
    from app.cli import http as client_http
    from app.main import create_app

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from fastapi.testclient import TestClient
    app = create_app()

    def in_process() -> Any:
        return TestClient(app, headers={"Authorization": f"Bearer {api.keys['admin']}"})

    monkeypatch.setattr(client_http, "connect", in_process)
    # Wide enough for every column's header on one line. COLUMNS alone is read when the
    # client's console is made, which an earlier test in the same process may have done.
    monkeypatch.setenv("COLUMNS", "250")
    monkeypatch.setattr(client, "out", Console(width=250))
    return CliRunner()


def test_audit_prints_when_who_what_which_and_why(api: Api, run: CliRunner) -> None:
    robot = api.robot("kr16", cell="cell-12")
    tool = api.tool(robot["id"], "torch", slot=3)
    api.patch(f"/v1/tools/{tool['id']}", {"tolerance": {"max_rms_mm": 0.2}})
    api.manual(tool["id"], [0, 0, 150], note="data sheet")
    api.manual(tool["id"], [0, 0, 152], activate="never")
    api.post(f"/v1/tools/{tool['id']}/versions/2/activate", scope="calibrate")

    result = run.invoke(cli, ["audit", "--tool", tool["id"]])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    header = next(line for line in lines if "when (UTC)" in line)
    for column in ("who", "what", "tool / version", "why"):
        assert column in header
    body = [line for line in lines if "torch" in line]
    assert "version.activate" in body[0]  # newest first
    assert "v2" in body[0]
    assert "test-calibrate" in body[0]
    assert "explicit (was v1)" in body[0]
    assert any("tolerance.max_rms_mm 0.5 -> 0.2" in line for line in body)
    assert any("manual accepted: data sheet" in line for line in body)

    only = run.invoke(cli, ["audit", "--action", "robot.create", "--actor", "test-admin"])
    assert only.exit_code == 0, only.output
    assert "robot.create" in only.output
    assert "tool.create" not in only.output

    refused = run.invoke(cli, ["audit", "--since", "yesterday"])
    assert refused.exit_code == 4, refused.output
    assert "since" in refused.output


def test_audit_needs_an_admin_key(
    api: Api, run: CliRunner, monkeypatch: pytest.MonkeyPatch
) -> None:
    from fastapi.testclient import TestClient

    from app.cli import http as client_http
    from app.main import create_app

    app = create_app()
    monkeypatch.setattr(
        client_http,
        "connect",
        lambda: TestClient(app, headers={"Authorization": f"Bearer {api.keys['read']}"}),
    )
    result = run.invoke(cli, ["audit"])
    assert result.exit_code == 5, result.output
    assert "403" in result.output


def test_why_in_a_few_words() -> None:
    assert audit_why("key.create", {"name": "pc", "scope": "read", "cells": ["cell-12"]}) == (
        "name pc, scope read, cells cell-12"
    )
    update = {"changed": ["cell", "kinematics"], "from": {"cell": "a"}, "to": {"cell": "b"}}
    assert audit_why("robot.update", update) == "cell a -> b; kinematics"
    assert audit_why("tool.check", {"summary": "moved 0.3 mm"}) == "moved 0.3 mm"


def test_why_never_says_none_and_rounds_its_figures() -> None:
    state = {
        "previous_state": None,
        "target": "UTOOL[3]",
        "version": 7,
        "controller": {"position_mm": [1.0, 2.0, 3.0]},
        "deviation_mm": 6.2370441069042215e-06,
        "deviation_deg": 0.5000000012,
        "error": None,
    }
    drifted = audit_why("controller.drifted", state)
    assert drifted == "drifted at UTOOL[3]: off by 0.000 mm, 0.500 deg"
    key = audit_why("key.create", {"name": "pc", "scope": "read", "cells": None})
    assert key == "name pc, scope read"
    moved = audit_why(
        "tool.update", {"changed": ["tolerance"], "from": {"tolerance": {"check_mm": None}},
                        "to": {"tolerance": {"check_mm": 0.30000000000000004}}}
    )  # fmt: skip
    assert moved == "tolerance.check_mm - -> 0.3"
    for text in (drifted, key, moved):
        assert "None" not in text
        assert "e-0" not in text


def test_why_of_a_deployment_and_a_forced_activation() -> None:
    failed = {
        "status": "not_written",
        "version": 3,
        "protocol": "fanuc_rmi",
        "target": "UTOOL[3]",
        "error": {
            "type": "x",
            "detail": "cannot connect to 127.0.0.1:16001",
            "controller_message": None,
        },
    }
    assert audit_why("tool.deploy", failed) == (
        "not_written at UTOOL[3] (fanuc_rmi): cannot connect to 127.0.0.1:16001"
    )
    forced = {"kind": "forced", "reason": "probe bent", "previous_version": 3, "force": True}
    assert audit_why("version.activate", forced) == "forced: probe bent (was v3)"


def test_audit_rows_carry_the_version_and_fit_80_columns(
    api: Api, run: CliRunner, monkeypatch: pytest.MonkeyPatch
) -> None:
    from app.cli import client
    from tests.api.controller_rigs import rig
    from tests.api.test_deployments import _setup

    with rig("kuka_kvp") as r:
        tool = _setup(api, r, name="torch")["tool"]
        deployed = api.post(f"/v1/tools/{tool['id']}/deployments", {}, scope="calibrate")
        assert deployed.status_code == 201, deployed.text
    monkeypatch.setattr(client, "out", Console(width=80))
    result = run.invoke(cli, ["audit", "--tool", tool["id"]])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert max(len(line) for line in lines) <= 80
    at = next(i for i, line in enumerate(lines) if "tool.deploy" in line)
    assert lines[at].endswith("tool.deploy  torch v1"), lines[at]
    assert lines[at + 1].rstrip() == "    verified at $TOOL_DATA[3] (kuka_kvp)"
    assert "None" not in result.output


def test_keys_create_with_cells(db: Database) -> None:
    runner = CliRunner()
    made = runner.invoke(
        cli, ["keys", "create", "--scope", "read", "--name", "pc", "--cells", "cell-12,cell-7"]
    )
    assert made.exit_code == 0, made.output
    assert "cells: cell-12, cell-7" in made.output
    listed = runner.invoke(cli, ["keys", "list"])
    assert "cells cell-12,cell-7" in listed.output
    bad = runner.invoke(cli, ["keys", "create", "--scope", "read", "--name", "pc", "--cells", ","])
    assert bad.exit_code == 2, bad.output
    assert "cells" in bad.output
    from app.storage.db import session_scope
    from app.storage.models import ApiKey, AuditEvent

    with session_scope(write=False) as session:
        rows = session.query(ApiKey).all()
        events = session.query(AuditEvent).all()
    assert [r.cells for r in rows] == [["cell-12", "cell-7"]]
    assert [(e.action, e.actor[:4], e.request_id) for e in events] == [("key.create", "cli:", None)]
