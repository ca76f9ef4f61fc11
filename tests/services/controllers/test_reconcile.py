"""Issue 50: what a reconcile round reads of the database before it talks to the controller
(the read transaction every robot's round opens)."""

from __future__ import annotations

import re
from typing import Any

import pytest
from sqlalchemy import event

from app.services.controllers import reconcile
from app.services.controllers.watcher import WATCHER
from app.storage.db import get_engine
from tests.api.controller_rigs import rig
from tests.api.test_deployments import _setup
from tests.conftest import Api


def test_a_rounds_read_transaction_reads_the_robot_once(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The robot's row is read once, with its controller, in one statement (get_controller,
    which answers 404 for the robot and 409 for no controller, only when that finds none): the
    round read it a second time before, then once beside a statement for the controller; the
    read transaction is that statement and one for each subject's rows (those on the
    driver's cursor, app.storage.db.HeldRead, counted where they are sent)."""
    from app.storage import db as storage

    with rig("kuka_kvp") as r:
        robot_id = _setup(api, r)["robot"]["id"]
        sent: list[str] = []

        def record(*args: Any) -> None:
            sent.append(str(args[2]))

        fetch = storage._fetch

        def held(conn: Any, sql: str, args: Any) -> Any:
            sent.append(sql)
            return fetch(conn, sql, args)

        monkeypatch.setattr(storage, "_fetch", held)

        engine = get_engine()
        event.listen(engine, "before_cursor_execute", record)
        try:
            read = reconcile._read_round(robot_id, WATCHER)
        finally:
            event.remove(engine, "before_cursor_execute", record)
    assert [c.subject_id for c in read.checks]  # the tool, and the controller read
    assert read.live.error is None
    from_robots = [sql for sql in sent if re.search(r"\b(FROM|JOIN) robots\b", sql)]
    assert len(from_robots) == 1, from_robots
    assert "FROM robot_controllers JOIN robots" in from_robots[0], from_robots
    assert len([sql for sql in sent if sql.lstrip().startswith("SELECT")]) == 3, sent
