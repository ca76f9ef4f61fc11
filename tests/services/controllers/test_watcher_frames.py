"""The watcher reads frames beside tools (issue 48, "What it must show"): beside a hung
controller, a pendant edit of a deployed frame's BASE_DATA is drifted on the frame's fleet
row, and a robot switched to a base holding an older version's values is flagged
moving_in_stale_frame, each by the first round to begin after it, within one interval."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from typing import Any

import pytest

from app.storage.db import session_scope
from app.storage.models import RobotLiveFrame
from tests.api.controller_rigs import SLOT, TIMEOUT_S, Rig, rig
from tests.api.frame_versions import base_at_two_versions
from tests.api.test_deployments import _setup
from tests.conftest import Api
from tests.polling import wait_for
from tests.services.controllers.test_watcher import (
    HUNG_TIMEOUT_S,
    INTERVAL_S,
    START_MARGIN_S,
    _after_a_round,
)
from tests.services.controllers.test_watcher import watching as watching  # the watcher on

#: BASE_DATA[BASE] as first taught (v1) and as calibrated since (v2, the active one), mm.
OLD_BASE = [800.0, -140.0, 400.0]
NEW_BASE = [812.5, -140.25, 402.0]
BASE = 2
#: BASE_DATA[BASE] edited on the pendant after v2 was deployed: 0.5 mm off in y
EDITED = [NEW_BASE[0], NEW_BASE[1] + 0.5, NEW_BASE[2]]
#: another base of the controller, holding v1's values (the pendant's copy of the old base)
OLD_COPY = 5
#: what a round may take beyond its interval to flag: the hung read is not waited for
WITHIN_S = 2 * INTERVAL_S + TIMEOUT_S + 1.0


@dataclass(frozen=True)
class FrameRead:
    """One reconcile of the robot by the watcher: when it began and ended (monotonic), the
    frame's state it stored, and the (frame_id, version) the robot moves in after it."""

    began: float
    ended: float
    state: str | None
    live: tuple[str | None, int | None] | None


def _frame_reads(monkeypatch: pytest.MonkeyPatch, robot_id: str, frame_id: str) -> list[FrameRead]:
    """Every reconcile of `robot_id` by the running watcher from now on, as it ends."""
    from app.services.controllers import reconcile as rounds
    from app.services.controllers import watcher

    reads: list[FrameRead] = []
    reconcile = rounds.reconcile_robot

    def recorded(**kwargs: Any) -> Any:
        began = time.monotonic()
        answer = reconcile(**kwargs)
        ended = time.monotonic()
        if kwargs["robot_id"] == robot_id and answer is not None:
            states = [f.state for f in answer.frames if f.frame_id == frame_id]
            with session_scope(write=False) as session:
                row = session.get(RobotLiveFrame, robot_id)
                live = None if row is None else (row.frame_id, row.version)
            reads.append(FrameRead(began, ended, states[0] if states else None, live))
        return answer

    monkeypatch.setattr(watcher, "reconcile_robot", recorded)
    return reads


def _frame_row(api: Api, frame_id: str) -> dict[str, Any]:
    listed = api.get("/v1/frames")
    assert listed.status_code == 200, listed.text
    [row] = [item for item in listed.json()["items"] if item["id"] == frame_id]
    return dict(row)


def _first_after(reads: list[FrameRead], moment: float) -> FrameRead:
    wait_for(
        lambda: any(read.began > moment for read in list(reads)),
        WITHIN_S,
        "a watcher read begun after the change",
    )
    return next(read for read in list(reads) if read.began > moment)


@contextmanager
def _beside_a_hung_controller(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> Iterator[tuple[Rig, Rig, str, list[FrameRead]]]:
    """A KUKA robot whose controller accepts and never answers (timeout_s 30), and another
    moving by its tool in base BASE, its frame there at v2 (NEW_BASE) deployed, v1 OLD_BASE;
    the watcher's reads of that robot from then on."""
    with rig("kuka_kvp") as hung, rig("kuka_kvp") as live:
        hung.sim.stalled = True
        hung_robot = _setup(api, hung, timeout_s=HUNG_TIMEOUT_S)["robot"]["id"]
        assert api.patch(f"/v1/robots/{hung_robot}", {"name": "hung"}).status_code == 200
        ids = _setup(api, live)
        robot_id = ids["robot"]["id"]
        live.sim.select_tool(SLOT)
        frame_id = base_at_two_versions(api, robot_id, BASE, OLD_BASE, NEW_BASE)
        deployed = api.post(f"/v1/frames/{frame_id}/deployments", {}, scope="calibrate")
        assert deployed.status_code == 201, deployed.text
        live.sim.set_base_data(OLD_COPY, *OLD_BASE, 0.0, 0.0, 0.0)
        live.sim.select_base(BASE)
        yield live, hung, frame_id, _frame_reads(monkeypatch, robot_id, frame_id)


def _row_when(api: Api, frame_id: str, holds: Any, what: str) -> dict[str, Any]:
    rows: list[dict[str, Any]] = []

    def seen() -> bool:
        rows.append(_frame_row(api, frame_id))
        return bool(holds(rows[-1]))

    try:
        wait_for(seen, WITHIN_S, what)
    except AssertionError as exc:
        raise AssertionError(f"{exc}: {rows[-1] if rows else None}") from exc
    return rows[-1]


def _changed_after_a_round(
    api: Api, frame_id: str, before: Callable[[dict[str, Any]], bool], change: Callable[[], None]
) -> float:
    """Once the frame's fleet row holds `before` (the hung robot's read is not waited for: it
    runs beside the others), `change` just after a round ended; when it was made."""
    _row_when(api, frame_id, before, "the frame's row before the change")
    _after_a_round(api, WITHIN_S)
    change()
    return time.monotonic()


def _controller(state: str) -> Callable[[dict[str, Any]], bool]:
    return lambda row: bool((row["controller"] or {}).get("state") == state)


def _in_active_version(row: dict[str, Any]) -> bool:
    return bool(row["live"]["state"] == "active")


def _stale(row: dict[str, Any]) -> bool:
    return "moving_in_stale_frame" in row["attention"]


def _flagged(
    api: Api, frame_id: str, reads: list[FrameRead], since: float, holds: Any, what: str
) -> tuple[dict[str, Any], FrameRead]:
    """The frame's fleet row once it `holds`, and the first watcher read begun after
    `since`: begun within one interval of it, its controller read within its timeout."""
    row = _row_when(api, frame_id, holds, what)
    first = _first_after(reads, since)
    assert first.began - since <= INTERVAL_S + START_MARGIN_S, (first, since)
    assert first.ended - first.began <= TIMEOUT_S, first
    return row, first


def test_a_pendant_edit_of_a_frame_is_drifted_within_one_interval_beside_a_hung_controller(
    watching: float, api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    with _beside_a_hung_controller(api, monkeypatch) as (live, hung, frame_id, reads):
        edit = partial(live.sim.set_base_data, BASE, *EDITED, 0.0, 0.0, 0.0)  # behind our back
        edited = _changed_after_a_round(api, frame_id, _controller("in_sync"), edit)
        row, first = _flagged(api, frame_id, reads, edited, _controller("drifted"), "drifted")
        assert first.state == "drifted", (first, reads)  # the first round after it flags it
        assert "controller_drifted" in row["attention"], row
        assert hung.sim.connections_accepted >= 1  # the hung controller was read meanwhile


def test_a_robot_switched_to_an_older_base_is_moving_in_stale_frame_within_one_interval(
    watching: float, api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    with _beside_a_hung_controller(api, monkeypatch) as (live, hung, frame_id, reads):
        switch = partial(live.sim.select_base, OLD_COPY)  # the pendant: the base holding v1
        switched = _changed_after_a_round(api, frame_id, _in_active_version, switch)
        row, first = _flagged(api, frame_id, reads, switched, _stale, "moving_in_stale_frame")
        assert first.live == (frame_id, 1), (first, reads)  # the first round after it flags it
        assert (row["live"]["state"], row["live"]["version"]) == ("stale_version", 1), row
        assert row["live"]["number"] == OLD_COPY, row
        assert row["controller"]["state"] == "in_sync", row  # BASE_DATA[BASE] untouched
        assert hung.sim.connections_accepted >= 1  # the hung controller was read meanwhile
