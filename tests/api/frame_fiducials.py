"""A frame calibrated from touches of a fixture's points (testbed.sim.cell_frames), its
calibration keeping them as fiducials, and those fiducials touched again where a move put
them: for the tests of a frame's re-check after a move."""

from __future__ import annotations

from typing import Any

import numpy as np

from app.kinematics.poses import pose_to_format
from testbed.sim.cell_frames import FIXTURE_MM, touch_frame
from tests.conftest import Api

NAMES = ["a", "b", "c", "d", "pin1", "pin2"]
POINTER_TCP = [1.5, -2.0, 180.0]
LIMITS = {"check_mm": 0.5, "max_correction_mm": 5.0, "touch_noise_mm": 0.05}


def calibrated_frame(
    api: Api,
    robot_id: str,
    name: str,
    R: np.ndarray,
    o: np.ndarray,
    *,
    pointer_id: str,
    fields: dict[str, Any] | None = None,
    **tolerance: float,
) -> dict[str, Any]:
    """A frame registered and calibrated by fit_points at (R, o) from noise-free touches of
    the fixture's points (POST /v1/frames/{frame_id}/calibrations, activated), its fiducials
    then named NAMES (PUT /v1/frames/{frame_id}/fiducials); `fields`: the frame's other
    fields (where it lives in a controller)."""
    made = api.post(
        f"/v1/robots/{robot_id}/frames",
        {"name": name, "kind": "base", "tolerance": {**LIMITS, **tolerance}, **(fields or {})},
    )
    assert made.status_code == 201, made.text
    frame = dict(made.json())
    body = touches(pointer_id, R, o, seed=1)
    for touch, nominal in zip(body["touches"], FIXTURE_MM, strict=True):
        touch["nominal_mm"] = nominal.tolist()
        del touch["fiducial"]
    calibrated = api.post(
        f"/v1/frames/{frame['id']}/calibrations",
        {"method": "fit_points", **body, "activate": "always"},
        scope="calibrate",
    )
    assert calibrated.status_code == 201, calibrated.text
    named = api.request(
        "PUT", f"/v1/frames/{frame['id']}/fiducials", "calibrate", json={"names": NAMES}
    )
    assert named.status_code == 200, named.text
    frame["active_version"] = calibrated.json()["version"]
    return frame


def cell(api: Api, vendor: str | None = "KUKA") -> tuple[dict[str, Any], dict[str, Any]]:
    """A robot (`vendor` None: any protocol is its controller's) and its pointer, calibrated."""
    robot = api.robot("kr16", **({"vendor": vendor} if vendor else {}))
    pointer = api.tool(robot["id"], "pointer")
    api.manual(pointer["id"], POINTER_TCP)
    return robot, pointer


def touches(
    pointer_id: str, R: np.ndarray, o: np.ndarray, names: list[str] | None = None, seed: int = 49
) -> dict[str, Any]:
    """The fixture's fiducials touched where the frame (R, o) puts them now (noise-free)."""
    chosen = names or NAMES
    nominal = FIXTURE_MM[[NAMES.index(n) for n in chosen]]
    touched = touch_frame(
        np.random.default_rng(seed), nominal, frame=(R, o), tcp_mm=np.array(POINTER_TCP)
    )
    return {
        "tool_id": pointer_id,
        "format": "matrix",
        "touches": [
            {"fiducial": n, "pose": pose_to_format("matrix", rot, pos)}
            for n, rot, pos in zip(chosen, touched.rotations, touched.positions_mm, strict=True)
        ],
    }
