"""No secret in any response, log line, audit event or backup, for every protocol.

Which protocols have a secret: ABB's RWS 1.0 and 2.0 (`abb_rws1`, `abb_rws2`) log in with a
user name and password, the one credential any connector sends. KUKAVARPROXY (`kuka_kvp`),
FANUC's RMI (`fanuc_rmi`), Yaskawa's HSES (`yaskawa_hses`), UR's RTDE and secondary
interface (`ur_rtde`) and Techman's Listen node and Ethernet Slave (`techman`) take none: a
controller of theirs can still be stored with a password (the API takes one for every
protocol, and the settings every connector is opened with carry it), so each is held to the
same rule: a password stored, a deployment, a reconcile, a pose read and the lists after them
show it nowhere. ABB's simulator is given the password, so that its sessions log in with it.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from app.storage.backup import backup
from app.vendors.registry import WIRE_PROTOCOLS
from tests.api.controller_rigs import ABB_USER, rig
from tests.api.controller_rigs import secret_key as secret_key  # autouse: stored passwords
from tests.conftest import Api, Database

SECRET = "Pa55-not-to-be-seen-7f3e1b"
#: The protocols whose connector sends the password (the rest take no credential).
WITH_CREDENTIALS = {"abb_rws1", "abb_rws2"}


def _backup_text(db: Database, tmp_path: Path) -> bytes:
    """`tcpcal db backup`'s copy, as bytes a secret in clear would show in: the SQLite file
    itself, or PostgreSQL's custom-format dump (compressed) turned back into SQL."""
    copy = tmp_path / "backup.copy"
    backup(db.url, copy)
    if db.backend == "sqlite":
        return copy.read_bytes()
    pg_restore = shutil.which("pg_restore")
    assert pg_restore, "pg_restore is needed to read a PostgreSQL backup"
    return subprocess.run(
        [pg_restore, "--file=-", str(copy)], check=True, capture_output=True
    ).stdout


@pytest.mark.parametrize("protocol", list(WIRE_PROTOCOLS))
def test_a_stored_password_is_in_no_answer_log_audit_event_or_backup(
    api: Api,
    db: Database,
    protocol: str,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    capfd: pytest.CaptureFixture[str],
) -> None:
    caplog.set_level(logging.DEBUG)
    texts: list[str] = []
    with rig(protocol) as r:
        if protocol in WITH_CREDENTIALS:
            r.sim.users = {ABB_USER: SECRET}  # its sessions log in with the stored password
        robot = api.robot()
        body = r.controller_body(password=SECRET)
        put = api.request("PUT", f"/v1/robots/{robot['id']}/controller", "admin", json=body)
        assert put.status_code == 200, put.text
        assert put.json()["has_password"] is True
        tool = api.tool(robot["id"], **r.tool_fields)
        api.manual(tool["id"], [10.0, -5.0, 180.0])
        answers: list[Any] = [
            put,
            api.get(f"/v1/robots/{robot['id']}/controller"),
            api.post(f"/v1/tools/{tool['id']}/deployments", {}, scope="calibrate"),
            api.post(f"/v1/robots/{robot['id']}/reconcile", scope="read"),
            api.get(f"/v1/robots/{robot['id']}/controller/pose", scope="calibrate"),
            api.get(f"/v1/tools/{tool['id']}/deployments"),
            api.get("/v1/robots"),
            api.get("/v1/fleet"),
        ]
        # the sessions happened (ABB's logged in with the password): the check is not empty
        assert answers[2].status_code == 201, answers[2].text
        assert answers[4].status_code == 200, answers[4].text
        audit = api.get("/v1/audit", params={"robot_id": robot["id"]}, scope="admin")
        assert audit.json()["items"], "no audit event to look into"
        texts += [a.text for a in answers] + [audit.text]
    captured = capfd.readouterr()
    assert caplog.records, "no log line to look into"
    texts += [captured.out, captured.err, caplog.text]
    texts += [repr(record.msg) for record in caplog.records]
    found = [i for i, t in enumerate(texts) if SECRET in t]
    assert found == [], f"the password is in {[texts[i][:200] for i in found]}"
    assert SECRET.encode() not in _backup_text(db, tmp_path)
