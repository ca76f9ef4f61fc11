"""LiveTool.matches: every version of the robot's live tools equal to the frame the robot
moves by, within the reconcile's 0.01 mm and 0.01 deg, and nothing of another robot's or an
archived tool's."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from app.services.robots.live_tool import live_tool_matches
from app.storage.db import session_scope
from app.vendors.connector import Frame
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
