"""No secret in any response, log line, audit event or backup, for every protocol.

Which protocols have a secret: ABB's RWS 1.0 and 2.0 (`abb_rws1`, `abb_rws2`) log in with a
user name and password, the one credential any connector sends. KUKAVARPROXY (`kuka_kvp`),
FANUC's RMI (`fanuc_rmi`), Yaskawa's HSES (`yaskawa_hses`), UR's RTDE and secondary
interface (`ur_rtde`) and Techman's Listen node and Ethernet Slave (`techman`) take none: a
controller of theirs can still be stored with a password (the API takes one for every
protocol, and the settings every connector is opened with carry it), so each is held to the
same rule: a password stored, a deployment, a reconcile, a pose read and the lists after them
show it nowhere. ABB's simulator is given the password, so that its sessions log in with it.
A frame's paths are held to it too (issue 48), on every controller that writes frames.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.storage.backup import backup
from app.vendors.registry import WIRE_PROTOCOLS
from tests.api.controller_rigs import ABB_USER, rig
from tests.api.controller_rigs import secret_key as secret_key  # autouse: stored passwords
from tests.api.frame_fiducials import touches
from tests.api.test_frame_checks import O_FIXTURE, R_FIXTURE, _moved_in_frame, _on_controller
from tests.conftest import Api, Database
from tests.controllers.simbase import go_silent
from tests.vendors.test_frame_cuts import CASES

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
    api: Api, protocol: str, nowhere: Callable[[list[str]], None]
) -> None:
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
    nowhere(texts)


@pytest.fixture
def nowhere(
    db: Database,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    capfd: pytest.CaptureFixture[str],
) -> Callable[[list[str]], None]:
    """Every line logged from here on kept; the check that SECRET is in none of the answers'
    and audit's `texts` it is given, no line logged or printed, and not in the backup."""
    caplog.set_level(logging.DEBUG)

    def check(texts: list[str]) -> None:
        _assert_nowhere(texts, db, tmp_path, caplog, capfd)

    return check


def _assert_nowhere(
    texts: list[str],
    db: Database,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    capfd: pytest.CaptureFixture[str],
) -> None:
    captured = capfd.readouterr()
    assert caplog.records, "no log line to look into"
    texts = [*texts, captured.out, captured.err, caplog.text]
    texts += [repr(record.msg) for record in caplog.records]
    found = [i for i, t in enumerate(texts) if SECRET in t]
    assert found == [], f"the password is in {[texts[i][:200] for i in found]}"
    assert SECRET.encode() not in _backup_text(db, tmp_path)


@pytest.mark.parametrize("protocol", sorted(CASES))
def test_a_stored_password_is_in_no_answer_log_audit_event_or_backup_for_frames(
    api: Api, protocol: str, nowhere: Callable[[list[str]], None]
) -> None:
    """The frames' paths (issue 48): a frame created and calibrated on a controller with a
    password, deployed verified and once cut after the write, reconciled, checked and
    corrected with its deployment, the fleet of frames, the frame table and the frames'
    audit events show it nowhere, nor does the backup after them."""
    with rig(protocol) as r:
        if protocol in WITH_CREDENTIALS:
            r.sim.users = {ABB_USER: SECRET}
        robot, pointer, frame = _on_controller(api, r, None, password=SECRET)
        deployments = f"/v1/frames/{frame['id']}/deployments"
        verified = api.post(deployments, {}, scope="calibrate")
        assert verified.status_code == 201, verified.text
        assert verified.json()["status"] == "verified"
        r.sim.fault = go_silent("after", CASES[protocol].write)
        cut = api.post(deployments, {}, scope="calibrate")
        assert cut.status_code == 502, cut.text
        r.sim.stalled = False
        r.sim.fault = None
        reconciled = api.post(f"/v1/robots/{robot['id']}/reconcile", scope="read")
        assert reconciled.status_code == 200, reconciled.text
        assert reconciled.json()["frames"], "no frame reconciled"
        along = R_FIXTURE @ (1.5 * np.array([-300.0, 500.0, 0.0]) / np.hypot(300.0, 500.0))
        R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(along), 0.3)
        moved = {**touches(pointer["id"], R1, o1), "correct": "within_limits", "reason": "moved"}
        check = api.post(f"/v1/frames/{frame['id']}/checks", moved, scope="calibrate")
        assert check.status_code == 201, check.text
        assert check.json()["correction"]["deployment"]["status"] == "verified"
        answers: list[Any] = [
            api.get(f"/v1/robots/{robot['id']}/controller"),
            verified,
            cut,
            reconciled,
            check,
            api.get(f"/v1/frames/{frame['id']}"),
            api.get(f"/v1/frames/{frame['id']}/calibrations"),
            api.get(deployments),
            api.get("/v1/frames"),
            api.get(f"/v1/robots/{robot['id']}/frames"),
            api.get(f"/v1/robots/{robot['id']}/frame-table"),
        ]
        audit = api.get("/v1/audit", params={"frame_id": frame["id"]}, scope="admin")
        assert audit.json()["items"], "no audit event to look into"
        texts = [a.text for a in answers] + [audit.text]
    nowhere(texts)
