"""A base to teach on a live server, and its touches typed as a pendant shows them: what the
frame page's browser test and calibrate-frame's terminal test share."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_to_format
from testbed.live_server import LiveServer

#: The pointer's TCP (mm, flange frame), pointing down at every touch.
TCP = np.array([0.0, 0.0, 150.0])
DOWN = Rotation.from_euler("x", 180, degrees=True)
#: The base's origin (robot base, mm) and its +X and XY touches (its axes are the robot's).
ORIGIN = np.array([900.0, 100.0, 300.0])
X_TOUCH = ORIGIN + np.array([300.0, 0.0, 0.0])
XY_TOUCH = ORIGIN + np.array([0.0, 200.0, 0.0])


def typed(point: np.ndarray) -> str:
    """The kuka_abc pose that puts the pointer's TCP on `point`, as typed at a pendant."""
    flange = point - DOWN.apply(TCP)
    pose = np.ravel(pose_to_format("kuka_abc", DOWN.as_matrix(), flange))
    return " ".join(f"{v:.6f}" for v in pose)


def base_to_teach(
    server: LiveServer, robot_name: str = "kr16"
) -> tuple[dict[str, Any], dict[str, Any]]:
    """A KUKA robot's base 2 (touch noise 0.05 mm) and its pointer with an active TCP (one
    robot of each name a server)."""
    with server.client() as http:
        robot = http.post("/v1/robots", json={"name": robot_name, "vendor": "KUKA"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "pointer"}).json()
        manual = {"method": "manual", "tcp": {"position_mm": TCP.tolist()}}
        assert http.post(f"/v1/tools/{tool['id']}/calibrations", json=manual).is_success
        frame = http.post(
            f"/v1/robots/{robot['id']}/frames",
            json={"name": "fixture-a", "kind": "base", "slot": 2,
                  "tolerance": {"touch_noise_mm": 0.05}},
        ).json()  # fmt: skip
    return frame, tool
