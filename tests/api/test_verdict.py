"""Every result says its verdict in one sentence; a large jump is stored but not activated."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from app.jsontypes import JsonObject
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses
from tests.conftest import Api


def _tool(api: Api) -> str:
    robot = api.robot("kr16")
    return str(api.tool(robot["id"], "torch", slot=3)["id"])


def _stacked(poses: list[Any]) -> JsonObject:
    """An N-point body fitted by plain least squares: it sets no touch aside, so a missed
    touch stays in the fit and in the verdict (the robust default would set it aside)."""
    return {
        "method": "xyz_npoint",
        "format": "xyz_wxyz",
        "poses": poses,
        "options": {"algorithm": "stacked"},
    }


def _calibrate(api: Api, tool_id: str, body: JsonObject) -> JsonObject:
    response = api.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate")
    assert response.status_code == 201, response.text
    result: JsonObject = response.json()
    return result


def test_150_mm_to_0_15_mm_is_versioned_not_active_with_the_move_named(api: Api) -> None:
    tool_id = _tool(api)
    first = _calibrate(api, tool_id, {"method": "manual", "tcp": {"position_mm": [0, 0, 150]}})
    assert (first["version"], first["active"], first["change_from_active_mm"]) == (1, True, None)

    slip = _calibrate(api, tool_id, {"method": "manual", "tcp": {"position_mm": [0, 0, 0.15]}})
    assert (slip["status"], slip["version"], slip["active"]) == ("accepted", 2, False)
    assert abs(float(slip["change_from_active_mm"]) - 149.85) < 1e-9
    warning = " ".join(slip["warnings"])
    assert "moved 149.85 mm from active version 1" in warning
    assert "max_change_mm 5 mm" in warning
    assert 'activate: "always"' in warning
    assert str(slip["summary"]).startswith("accepted but not activated:")
    assert api.get(f"/v1/tools/{tool_id}/tcp").json()["version"] == 1

    meant = _calibrate(
        api,
        tool_id,
        {"method": "manual", "tcp": {"position_mm": [0, 0, 0.15]}, "activate": "always"},
    )
    assert (meant["version"], meant["active"]) == (3, True)
    assert api.get(f"/v1/tools/{tool_id}/tcp").json()["version"] == 3


def test_a_small_move_is_activated_and_said_in_the_summary(api: Api) -> None:
    tool_id = _tool(api)
    touches = simulate_touches(8, seed=11, touch_noise_mm=0.05)
    before = [float(v) for v in np.add(touches.t, [0.3, -0.2, 0.1])]
    _calibrate(api, tool_id, {"method": "manual", "tcp": {"position_mm": before}})
    result = _calibrate(
        api, tool_id, {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(touches)}
    )
    assert result["active"] is True
    summary = str(result["summary"])
    match = re.fullmatch(
        r"accepted: TCP \((-?\d+\.\d\d), (-?\d+\.\d\d), (-?\d+\.\d\d)\) mm, "
        r"(\d+\.\d\d) mm rms over 8 touches, moved (\d+\.\d\d) mm from version 1",
        summary,
    )
    assert match, summary
    position = result["tcp"]["position_mm"]
    assert [float(v) for v in match.groups()[:3]] == [round(float(v), 2) for v in position]
    expected_change = float(np.linalg.norm(np.asarray(position) - before))
    assert float(match.group(5)) == round(expected_change, 2)
    assert not any("orientation kept" in w for w in result["warnings"])


def test_out_of_tolerance_names_the_missed_touch_from_one(api: Api) -> None:
    tool_id = _tool(api)
    touches = simulate_touches(8, seed=3, touch_noise_mm=0.02)
    poses = as_poses(touches)
    poses[4][0] += 3.0  # touch #5 (index 4) misses by 3 mm
    result = _calibrate(api, tool_id, _stacked(poses))
    assert result["status"] == "out_of_tolerance"
    assert re.match(
        r"out of tolerance: touch 5 is \d+\.\d\d mm off the others", str(result["summary"])
    )
    assert str(result["summary"]).endswith("touch it again")


def test_out_of_tolerance_names_every_touch_past_the_limit_not_only_the_worst(api: Api) -> None:
    tool_id = _tool(api)
    touches = simulate_touches(10, seed=3, touch_noise_mm=0.02)
    poses = as_poses(touches)
    poses[2][1] += 2.5  # touches 3 and 7 both miss
    poses[6][0] -= 3.5
    result = _calibrate(api, tool_id, _stacked(poses))
    assert result["status"] == "out_of_tolerance"
    quality = result["quality"]
    beyond = [i + 1 for i, r in enumerate(quality["residuals_mm"]) if r > 1.0]
    assert len(beyond) >= 2, quality["residuals_mm"]
    summary = str(result["summary"])
    named = ", ".join(str(n) for n in beyond[:-1]) + f" and {beyond[-1]}"
    assert summary.startswith(f"out of tolerance: touches {named} are "), summary
    figures = [f"{r:.2f}" for r in quality["residuals_mm"] if r > 1.0]
    assert f"are {', '.join(figures)} mm off the others" in summary, summary
    assert summary.endswith("touch them again")


def test_stateless_solve_has_a_summary_and_no_change(api: Api) -> None:
    touches = simulate_touches(6, seed=5, touch_noise_mm=0.01)
    response = api.post(
        "/v1/solve",
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(touches)},
        scope="read",
    )
    assert response.status_code == 200, response.text
    result = response.json()
    assert result["change_from_active_mm"] is None
    assert result["summary"].startswith("accepted: TCP (")
    assert "over 6 touches" in result["summary"]
