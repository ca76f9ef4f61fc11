"""LiveTool.matches: every version of the robot's live tools equal to the frame the robot
moves by, within the reconcile's 0.01 mm and 0.01 deg, and nothing of another robot's or an
archived tool's."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sqlalchemy import select

from app.helpers.frame_deviation import (
    SYNC_TOLERANCE_DEG,
    SYNC_TOLERANCE_MM,
    frame_deviation,
    frames_within,
    within,
)
from app.security.auth import Principal
from app.services.robots.live_tool import LiveRead, live_tool_matches, record_live
from app.storage.db import session_scope
from app.storage.models import AuditEvent, RobotLiveMatch, RobotLiveTool
from app.vendors.connector import Frame, LiveTool
from tests.conftest import Api

Q_TURNED = (0.9238795325112867, 0.0, 0.3826834323650898, 0.0)  # 45 deg about y


def _turned_by(quaternion: tuple[float, ...], degrees: float) -> tuple[float, float, float, float]:
    w, x, y, z = quaternion
    turned = Rotation.from_rotvec([0.0, 0.0, np.radians(degrees)]) * Rotation.from_quat(
        [x, y, z, w]
    )
    qx, qy, qz, qw = turned.as_quat()
    return float(qw), float(qx), float(qy), float(qz)


def _manual(api: Api, tool_id: str, tcp: dict[str, list[float]]) -> None:
    body = {"method": "manual", "tcp": tcp}
    done = api.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate")
    assert done.status_code == 201, done.text


def _matches(robot_id: str, frame: Frame | None) -> list[tuple[str, int, bool]]:
    with session_scope(write=False) as session:
        found = live_tool_matches(session, robot_id, frame)
    return [(m.tool_id, m.version, m.active) for m in found]


def test_every_equal_version_is_named_with_whether_it_is_active(api: Api) -> None:
    robot_id = api.robot("kr")["id"]
    torch, gripper = (api.tool(robot_id, name)["id"] for name in ("torch", "gripper"))
    tcp = {"position_mm": [10.0, 0.0, 250.0], "quaternion": list(Q_TURNED)}
    for tool_id in (torch, gripper):
        _manual(api, tool_id, tcp)
    _manual(api, torch, {"position_mm": [10.0, 0.0, 251.0], "quaternion": [1.0, 0.0, 0.0, 0.0]})
    other_robot = api.robot("kr2")["id"]
    _manual(api, api.tool(other_robot, "torch")["id"], tcp)

    live = Frame(position_mm=(10.0, 0.0, 250.0 + 0.009), quaternion=_turned_by(Q_TURNED, 0.009))
    assert _matches(robot_id, live) == [(torch, 1, False), (gripper, 1, True)]
    assert _matches(robot_id, Frame((10.0, 0.0, 251.0), (1.0, 0.0, 0.0, 0.0))) == [(torch, 2, True)]

    beyond_mm = Frame(position_mm=(10.0, 0.0, 250.011), quaternion=Q_TURNED)
    beyond_deg = Frame(position_mm=(10.0, 0.0, 250.0), quaternion=_turned_by(Q_TURNED, 0.011))
    assert _matches(robot_id, beyond_mm) == []
    assert _matches(robot_id, beyond_deg) == []
    assert _matches(robot_id, None) == []  # ABB: the controller does not say

    assert api.delete(f"/v1/tools/{gripper}").status_code in (200, 204)
    assert _matches(robot_id, live) == [(torch, 1, False)]  # an archived tool is not a match


# ---- record_live: what a round stores of the tool the robot moves by --------------------

T0 = datetime(2026, 12, 2, 4, 0, tzinfo=UTC)
ROUND = Principal(key_id="watcher", name="watcher", scope="read")


def _record(robot_id: str, tool: LiveTool | None, at: datetime, error: str | None = None) -> None:
    with session_scope(write=True) as session:
        record_live(session, robot_id=robot_id, live=LiveRead(tool, error), at=at, actor=ROUND)


def _stored(robot_id: str) -> tuple[RobotLiveTool, list[tuple[str, int]], list[AuditEvent]]:
    with session_scope(write=False) as session:
        row = session.get(RobotLiveTool, robot_id)
        assert row is not None
        session.expunge(row)
        found = session.execute(
            select(RobotLiveMatch.tool_id, RobotLiveMatch.version)
            .where(RobotLiveMatch.robot_id == robot_id)
            .order_by(RobotLiveMatch.tool_id)
        ).all()
        events = list(
            session.scalars(
                select(AuditEvent)
                .where(AuditEvent.robot_id == robot_id, AuditEvent.action == "robot.live_tool")
                .order_by(AuditEvent.id)
            )
        )
        for event in events:
            session.expunge(event)
    return row, [(t, v) for t, v in found], events


def test_a_round_stores_the_live_tool_and_a_change_once(api: Api) -> None:
    robot_id = api.robot("kr")["id"]
    torch = api.tool(robot_id, "torch")["id"]
    _manual(api, torch, {"position_mm": [10.0, 0.0, 250.0], "quaternion": list(Q_TURNED)})
    on_torch = LiveTool(5, Frame((10.0, 0.0, 250.0), Q_TURNED))

    _record(robot_id, on_torch, T0)  # the first read: a row, its matches, one event
    row, found, events = _stored(robot_id)
    assert (row.read, row.number, row.flange, row.error) == (True, 5, False, None)
    assert row.frame == {"position_mm": [10.0, 0.0, 250.0], "quaternion": list(Q_TURNED)}
    assert (row.since, row.checked_at) == (T0, T0)
    assert found == [(torch, 1)]
    assert len(events) == 1
    assert events[0].details is not None
    assert events[0].details["previous"] is None

    # the same frame, then one within 0.01 mm: checked again, no change, no event; the
    # frame stored is the one read last
    _record(robot_id, on_torch, T0 + timedelta(seconds=10))
    nudged = LiveTool(5, Frame((10.0, 0.0, 250.004), Q_TURNED))
    _record(robot_id, nudged, T0 + timedelta(seconds=20), error=None)
    row, found, events = _stored(robot_id)
    assert (row.since, row.checked_at) == (T0, T0 + timedelta(seconds=20))
    assert row.frame is not None
    assert row.frame["position_mm"] == [10.0, 0.0, 250.004]
    assert found == [(torch, 1)]
    assert len(events) == 1

    # the bare flange with no tool selected: a change (since, one event naming what was
    # before), no match left
    _record(robot_id, LiveTool(None, Frame((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))), T0 + H)
    row, found, events = _stored(robot_id)
    assert (row.read, row.number, row.flange, row.since) == (True, None, True, T0 + H)
    assert found == []
    assert len(events) == 2
    assert events[1].details is not None
    previous = events[1].details["previous"]
    assert isinstance(previous, dict)
    assert previous["matches"] == [{"tool_id": torch, "version": 1}]

    # unread (a refused read): a change, its error stored; unread again: checked, no change
    _record(robot_id, None, T0 + 2 * H, error="refused: $IPO_MODE #TCP")
    _record(robot_id, None, T0 + 3 * H, error="refused: $IPO_MODE #TCP")
    row, found, events = _stored(robot_id)
    assert (row.read, row.frame, row.error) == (False, None, "refused: $IPO_MODE #TCP")
    assert (row.since, row.checked_at, len(events)) == (T0 + 2 * H, T0 + 3 * H, 3)

    # a new version equal to the frame read: a change of the matches alone
    _record(robot_id, on_torch, T0 + 4 * H)
    _manual(api, torch, {"position_mm": [10.0, 0.0, 250.0], "quaternion": list(Q_TURNED)})
    _record(robot_id, on_torch, T0 + 5 * H)
    row, found, events = _stored(robot_id)
    assert found == [(torch, 1), (torch, 2)]
    assert row.since == T0 + 5 * H
    assert len(events) == 5


H = timedelta(hours=1)


@pytest.mark.parametrize("seed", range(3))
def test_frames_within_says_what_the_deviation_says(seed: int) -> None:
    """frames_within computes the rotation only for frames whose points are near: it answers
    as within(frame_deviation(...)) for frames near and far, turned and not."""
    rng = np.random.default_rng(seed)
    for _ in range(300):
        position = rng.uniform(-500, 500, 3)
        quaternion = Rotation.random(random_state=rng).as_quat(scalar_first=True)
        moved = position + rng.normal(0, 0.006, 3) * rng.choice([0.0, 1.0, 10.0])
        turned = _turned_by(tuple(quaternion), float(rng.normal(0, 0.008)) * rng.choice([0, 1]))
        a = (list(position), list(quaternion))
        b = (list(moved), list(turned))
        expected = within(frame_deviation(*a, *b), mm=SYNC_TOLERANCE_MM, deg=SYNC_TOLERANCE_DEG)
        assert frames_within(*a, *b, mm=SYNC_TOLERANCE_MM, deg=SYNC_TOLERANCE_DEG) == expected
    same = ([1.0, 2.0, 3.0], [1.0, 0.0, 0.0, 0.0])
    assert frames_within(*same, *same, mm=0.0, deg=0.0)
