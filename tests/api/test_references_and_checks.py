"""Reference points, the XYZ reference method across two tools, and drift checks."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses, row_counts
from tests.conftest import TABLES, Api

NOISE = 0.05


def _touch_pose(
    R: np.ndarray, t: np.ndarray, point: np.ndarray, rng: np.random.Generator, noise: float
) -> list[float]:
    """Flange pose at which TCP t (flange) touches `point` (base), with touch noise."""
    f = point - R @ t + rng.normal(0.0, noise, 3)
    return [*f, *Rotation.from_matrix(R).as_quat(scalar_first=True)]


def test_tool_b_from_tool_a_reference_matches_truth_within_propagated_sigma(api: Api) -> None:
    robot = api.robot("kr16")
    tol = {"touch_noise_mm": NOISE}
    tool_a = api.tool(robot["id"], "probe", slot=1, tolerance=tol)
    tool_b = api.tool(robot["id"], "gripper", slot=2, tolerance=tol)
    touches = simulate_touches(12, seed=21, touch_noise_mm=NOISE)
    cal_a = api.post(
        f"/v1/tools/{tool_a['id']}/calibrations",
        {
            "method": "xyz_npoint",
            "format": "xyz_wxyz",
            "poses": as_poses(touches),
            "options": {"save_reference_point": "pin"},
        },
        scope="calibrate",
    ).json()
    assert cal_a["quality"]["sigma_source"] == "configured"

    rng = np.random.default_rng(5)
    point = np.array([700.0, -150.0, 80.0])
    true_b = np.array([-20.0, 35.0, 210.0])
    R_a = Rotation.from_euler("xyz", [170, 10, 30], degrees=True).as_matrix()
    R_b = Rotation.from_euler("xyz", [-165, 5, -40], degrees=True).as_matrix()
    ref_pose = _touch_pose(R_a, touches.t, point, rng, NOISE)
    new_pose = _touch_pose(R_b, true_b, point, rng, NOISE)
    cal_b = api.post(
        f"/v1/tools/{tool_b['id']}/calibrations",
        {
            "method": "xyz_reference",
            "format": "xyz_wxyz",
            "poses": [new_pose],
            "options": {"reference_tool_id": tool_a["id"], "reference_pose": ref_pose},
        },
        scope="calibrate",
    )
    assert cal_b.status_code == 201, cal_b.text
    body = cal_b.json()
    sigma = np.asarray(body["quality"]["tcp_sigma_mm"])
    assert np.all(sigma > NOISE)  # two touches and tool A's own uncertainty
    assert np.all(sigma < 0.2)
    error = np.asarray(body["tcp"]["position_mm"]) - true_b
    assert np.all(np.abs(error) < 4 * sigma), (error, sigma)
    assert body["version"] == 1
    assert body["active"] is True

    # the same from the stored reference point of tool A's N-point calibration
    points = api.get(f"/v1/robots/{robot['id']}/reference-points").json()["items"]
    pin = points[0]
    touched = _touch_pose(R_b, true_b, np.asarray(touches.p), rng, NOISE)
    via_point = api.post(
        f"/v1/tools/{tool_b['id']}/calibrations",
        {
            "method": "xyz_reference",
            "format": "xyz_wxyz",
            "poses": [touched],
            "options": {"reference_point_id": pin["id"]},
        },
        scope="calibrate",
    )
    got = np.asarray(via_point.json()["tcp"]["position_mm"])
    sigma = np.asarray(via_point.json()["quality"]["tcp_sigma_mm"])
    assert np.all(np.abs(got - true_b) < 4 * sigma)


def test_reference_point_crud_and_refusals(api: Api) -> None:
    robot = api.robot()
    created = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "corner", "position_mm": [100, 200, 50]},
        scope="calibrate",
    )
    assert created.status_code == 201
    point = created.json()
    assert (point["source"], point["position_mm"]) == ("numeric", [100, 200, 50])
    one = api.get(f"/v1/robots/{robot['id']}/reference-points/{point['id']}").json()
    assert one["name"] == "corner"
    dup = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "corner", "position_mm": [0, 0, 0]},
        scope="calibrate",
    )
    assert dup.status_code == 409
    both = api.post(f"/v1/robots/{robot['id']}/reference-points", {"name": "x"}, scope="calibrate")
    assert both.status_code == 422


def test_reference_point_by_touch_of_a_trusted_tool(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    api.manual(tool["id"], [0, 0, 100])
    pose = [500, 0, 400, 0, 1, 0, 0]  # tool pointing down: TCP at z = 300
    created = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "pin", "touch": {"tool_id": tool["id"], "format": "xyz_wxyz", "pose": pose}},
        scope="calibrate",
    ).json()
    assert np.allclose(created["position_mm"], [500, 0, 300], atol=1e-9)
    assert created["source"].startswith(f"touch:{tool['id']}:v1")


def test_checks_inside_and_outside_tolerance_leave_active_tcp(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"], tolerance={"check_mm": 0.5})
    api.manual(tool["id"], [0, 0, 100])
    point = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "pin", "position_mm": [500, 0, 300]},
        scope="calibrate",
    ).json()
    good = api.post(
        f"/v1/tools/{tool['id']}/checks",
        {
            "reference_point_id": point["id"],
            "format": "xyz_wxyz",
            "poses": [[500.1, 0, 400, 0, 1, 0, 0]],
        },
        scope="calibrate",
    ).json()
    assert good["within_tolerance"] is True
    assert np.allclose(good["deviation_mm"], [-0.1, 0, 0], atol=1e-9)  # tip is 0.1 mm at -x
    assert abs(good["distance_mm"] - 0.1) < 1e-9
    # a bent torch: 2 mm off along the flange's y axis
    bent = api.post(
        f"/v1/tools/{tool['id']}/checks",
        {
            "reference_point_id": point["id"],
            "format": "xyz_wxyz",
            "poses": [[500, 2.0, 400, 0, 1, 0, 0], [500, 2.2, 400, 0, 1, 0, 0]],
        },
        scope="calibrate",
    ).json()
    assert bent["within_tolerance"] is False
    assert abs(bent["distance_mm"] - 2.2) < 1e-9
    # the flange is 2.2 mm further along base +y than the active TCP needs, so the tip has
    # moved along base -y, which is flange +y (the flange is turned 180 deg about x)
    assert np.allclose(bent["deviation_mm"], [0, -2.2, 0], atol=1e-9)
    assert np.allclose(bent["deviation_flange_mm"], [0, 2.2, 0], atol=1e-9)
    assert np.allclose(bent["mean_deviation_mm"], [0, -2.1, 0], atol=1e-9)
    assert bent["summary"] == (
        "out of tolerance: the tool tip is 2.20 mm from where version 1 puts it, "
        "2.20 mm along flange +Y (worst of 2 touches, limit 0.5 mm); "
        "recalibrate the tool or look for a bend"
    )
    assert good["summary"] == (
        "within tolerance: the tool tip is 0.10 mm from where version 1 puts it, "
        "0.10 mm along flange -X (limit 0.5 mm)"
    )
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["version"] == 1
    assert len(api.get(f"/v1/tools/{tool['id']}/versions").json()["items"]) == 1


def test_check_is_in_the_audit_trail(api: Api) -> None:
    from sqlalchemy import select

    from app.storage.db import session_scope
    from app.storage.models import AuditEvent

    robot = api.robot()
    tool = api.tool(robot["id"])
    api.manual(tool["id"], [0, 0, 100])
    point = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "pin", "position_mm": [500, 0, 300]},
        scope="calibrate",
    ).json()
    api.post(
        f"/v1/tools/{tool['id']}/checks",
        {
            "reference_point_id": point["id"],
            "format": "xyz_wxyz",
            "poses": [[503, 0, 400, 0, 1, 0, 0]],
        },
        scope="calibrate",
    )
    with session_scope(write=False) as session:
        events = session.scalars(select(AuditEvent).where(AuditEvent.action == "tool.check")).all()
    assert len(events) == 1
    assert events[0].actor == "test-calibrate"
    assert events[0].details is not None
    assert events[0].details["within_tolerance"] is False
    assert abs(events[0].details["distance_mm"] - 3.0) < 1e-9


def test_check_without_active_version_is_404_and_writes_nothing(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    point = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "pin", "position_mm": [0, 0, 0]},
        scope="calibrate",
    ).json()
    before = row_counts(TABLES)
    response = api.post(
        f"/v1/tools/{tool['id']}/checks",
        {
            "reference_point_id": point["id"],
            "format": "xyz_wxyz",
            "poses": [[0, 0, 100, 1, 0, 0, 0]],
        },
        scope="calibrate",
    )
    assert response.status_code == 404
    assert response.json()["type"].endswith("/no-active-version")
    assert row_counts(TABLES) == before
