"""The calibration workflow over HTTP with xyz_npoint: grade, version, activate, retry."""

from __future__ import annotations

from typing import Any

import httpx
import numpy as np
import pytest

from app.jsontypes import JsonObject
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses, row_counts, within
from tests.conftest import TABLES, Api


@pytest.fixture
def tool(api: Api) -> JsonObject:
    robot = api.robot("kr16")
    return api.tool(robot["id"], "torch", slot=3)


def _calibrate(api: Api, tool_id: str, body: JsonObject, **kw: Any) -> httpx.Response:
    return api.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate", **kw)


def test_eight_noisy_touches_accepted_active_and_served_as_kuka(api: Api, tool: JsonObject) -> None:
    touches = simulate_touches(8, seed=11, touch_noise_mm=0.05)
    response = _calibrate(
        api, tool["id"], {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(touches)}
    )
    assert response.status_code == 201, response.text
    cal = response.json()
    assert (cal["status"], cal["version"], cal["active"]) == ("accepted", 1, True)
    assert cal["algorithm"] == "robust"
    quality = cal["quality"]
    assert quality["n_poses"] == 8
    assert len(quality["residuals_mm"]) == 8
    assert quality["sigma_source"] == "residuals"
    assert 0 < quality["rms_mm"] < 0.2
    assert within(cal["tcp"]["position_mm"], touches.t, quality["tcp_sigma_mm"])
    assert np.allclose(cal["reference_point_mm"], touches.p, atol=0.5)

    served = api.get(f"/v1/tools/{tool['id']}/tcp?format=kuka").json()
    assert served["version"] == 1
    values = served["controller"]["values"]
    assert np.allclose(
        [values["X"], values["Y"], values["Z"]], cal["tcp"]["position_mm"], atol=1e-6
    )
    assert served["controller"]["text"].startswith("$TOOL_DATA[3]={X ")


def test_worse_result_is_out_of_tolerance_then_activated_then_rolled_back(
    api: Api,
    tool: JsonObject,
) -> None:
    good = _calibrate(
        api,
        tool["id"],
        {
            "method": "xyz_npoint",
            "format": "xyz_wxyz",
            "poses": as_poses(simulate_touches(8, seed=1)),
        },
    ).json()
    noisy = simulate_touches(8, seed=2, touch_noise_mm=1.5)
    bad = _calibrate(
        api,
        tool["id"],
        {
            "method": "xyz_npoint",
            "format": "xyz_wxyz",
            "options": {"algorithm": "stacked"},
            "poses": as_poses(noisy),
        },
    ).json()
    assert bad["status"] == "out_of_tolerance"
    assert bad["version"] == 2
    assert bad["active"] is False
    assert any("max_rms_mm" in w or "max_residual_mm" in w for w in bad["warnings"])
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["version"] == 1

    path = f"/v1/tools/{tool['id']}/versions/2/activate"
    refused = api.post(path, scope="calibrate")  # out of tolerance: force and a reason, or 409
    assert refused.status_code == 409
    assert refused.json()["type"].endswith("/out-of-tolerance")
    forced = api.post(path, {"force": True, "reason": "interim"}, scope="calibrate")
    assert forced.json()["active_version"] == 2
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["tcp"] == bad["tcp"]
    api.post(f"/v1/tools/{tool['id']}/versions/1/activate", scope="calibrate")
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["tcp"] == good["tcp"]
    listing = api.get(f"/v1/tools/{tool['id']}/versions").json()
    assert [v["status"] for v in listing["items"]] == ["accepted", "out_of_tolerance"]
    assert [(a["version"], a["activated_by"]) for a in listing["activations"]] == [
        (1, "test-calibrate"),
        (2, "test-calibrate"),
        (1, "test-calibrate"),
    ]


def test_activate_always_activates_out_of_tolerance(api: Api, tool: JsonObject) -> None:
    noisy = simulate_touches(8, seed=3, touch_noise_mm=1.5)
    cal = _calibrate(
        api,
        tool["id"],
        {
            "method": "xyz_npoint",
            "format": "xyz_wxyz",
            "activate": "always",
            "options": {"algorithm": "stacked"},
            "poses": as_poses(noisy),
        },
    ).json()
    assert (cal["status"], cal["active"]) == ("out_of_tolerance", True)


def test_idempotent_retry_creates_one_version(api: Api, tool: JsonObject) -> None:
    body = {
        "method": "xyz_npoint",
        "format": "xyz_wxyz",
        "poses": as_poses(simulate_touches(8, seed=4)),
    }
    headers = {"Idempotency-Key": "cell12-2026-11-22-001"}
    first = _calibrate(api, tool["id"], body, headers=headers)
    again = _calibrate(api, tool["id"], body, headers=headers)
    assert first.status_code == again.status_code == 201
    assert again.json() == first.json()
    assert again.headers.get("idempotent-replayed") == "true"
    assert [v["version"] for v in api.get(f"/v1/tools/{tool['id']}/versions").json()["items"]] == [
        1
    ]
    other = dict(body, note="different")
    conflict = _calibrate(api, tool["id"], other, headers=headers)
    assert conflict.status_code == 409
    assert conflict.json()["type"].endswith("/idempotency-key-reused")
    fresh = _calibrate(api, tool["id"], body, headers={"Idempotency-Key": "another"})
    assert fresh.json()["version"] == 2


@pytest.mark.parametrize(
    ("case", "kind"),
    [
        ("degenerate", "degenerate-poses"),
        ("sentinel", "out-of-range"),
        ("too_few", "too-few-poses"),
    ],
)
def test_unsolvable_input_is_422_and_writes_nothing(
    api: Api,
    tool: JsonObject,
    case: str,
    kind: str,
) -> None:
    from scipy.spatial.transform import Rotation

    touches = simulate_touches(8, seed=5, touch_noise_mm=0.0)
    poses = as_poses(touches)
    if case == "degenerate":
        # tool pointing down, then turned about base z only: one common axis, so the TCP
        # component along the flange's z is unobservable
        rotations = Rotation.from_euler(
            "xz", [[180.0, a] for a in np.linspace(0, 150, 6)], degrees=True
        )
        t = np.array([10.0, 0.0, 150.0])
        p = np.array([500.0, 0.0, 200.0])
        poses = [[*(p - r.apply(t)), *r.as_quat(scalar_first=True)] for r in rotations]
    elif case == "sentinel":
        poses[3][:3] = [-3.7e28, -3.7e28, -3.7e28]
    else:
        poses = poses[:3]
    before = row_counts(TABLES)
    response = _calibrate(
        api, tool["id"], {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": poses}
    )
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"].endswith("/" + kind)
    assert problem["detail"]
    if case == "degenerate":
        assert "add a touch" in problem["detail"].lower()
        # the unobservable direction is the flange's z axis (the common rotation axis)
        direction = np.asarray(problem["context"]["direction_flange"])
        assert np.allclose(np.abs(direction), [0, 0, 1], atol=1e-6)
    if case == "sentinel":
        assert problem["errors"][0]["loc"][:3] == ["body", "poses", 3]
    assert "NaN" not in response.text
    assert row_counts(TABLES) == before


def test_save_reference_point_registers_the_pivot(api: Api, tool: JsonObject) -> None:
    touches = simulate_touches(8, seed=6)
    cal = _calibrate(
        api,
        tool["id"],
        {
            "method": "xyz_npoint",
            "format": "xyz_wxyz",
            "options": {"save_reference_point": "pin-1"},
            "poses": as_poses(touches),
        },
    ).json()
    points = api.get(f"/v1/robots/{tool['robot_id']}/reference-points").json()["items"]
    assert [p["name"] for p in points] == ["pin-1"]
    assert points[0]["position_mm"] == cal["reference_point_mm"]
    assert points[0]["calibration_id"] == cal["id"]
    assert points[0]["covariance_mm2"] is not None


def test_idempotency_keys_expire_after_their_ttl(api: Api, tool: JsonObject) -> None:
    from datetime import timedelta

    from sqlalchemy import update

    from app.storage.db import session_scope
    from app.storage.models import IdempotencyRecord, utcnow

    body = {"method": "manual", "tcp": {"position_mm": [0, 0, 120]}}
    headers = {"Idempotency-Key": "k-1"}
    assert _calibrate(api, tool["id"], body, headers=headers).json()["version"] == 1
    with session_scope(write=True) as session:
        session.execute(update(IdempotencyRecord).values(created_at=utcnow() - timedelta(hours=25)))
    again = _calibrate(api, tool["id"], body, headers=headers)
    assert again.headers.get("idempotent-replayed") is None
    assert again.json()["version"] == 2


def test_metrics_count_calibrations_by_method_and_status(api: Api, tool: JsonObject) -> None:
    import re

    def count() -> int:
        text = api.get("/metrics").text
        found = re.search(
            r'tcpcal_calibrations_total\{method="manual",status="accepted"\} (\d+)', text
        )
        return int(found.group(1)) if found else 0

    before = count()
    api.manual(tool["id"], [0, 0, 100])
    assert count() == before + 1


def test_reference_point_not_saved_when_out_of_tolerance_says_so(
    api: Api, tool: JsonObject
) -> None:
    noisy = simulate_touches(8, seed=2, touch_noise_mm=1.5)
    cal = _calibrate(
        api,
        tool["id"],
        {
            "method": "xyz_npoint",
            "format": "xyz_wxyz",
            "options": {"algorithm": "stacked", "save_reference_point": "pin-2"},
            "poses": as_poses(noisy),
        },
    ).json()
    assert cal["status"] == "out_of_tolerance"
    assert any("'pin-2' not saved" in w for w in cal["warnings"])
    stored = api.get(f"/v1/calibrations/{cal['id']}").json()
    assert stored["warnings"] == cal["warnings"]
    assert api.get(f"/v1/robots/{tool['robot_id']}/reference-points").json()["items"] == []


def test_reference_point_name_clash_is_refused_before_solving(api: Api, tool: JsonObject) -> None:
    api.post(
        f"/v1/robots/{tool['robot_id']}/reference-points",
        {"name": "pin", "position_mm": [0, 0, 0]},
        scope="calibrate",
    )
    before = row_counts(TABLES)
    response = _calibrate(
        api,
        tool["id"],
        {
            "method": "xyz_npoint",
            "format": "xyz_wxyz",
            "options": {"save_reference_point": "pin"},
            "poses": as_poses(simulate_touches(8, seed=9)),
        },
    )
    assert response.status_code == 409
    assert response.json()["errors"][0]["loc"] == ["body", "options", "save_reference_point"]
    assert row_counts(TABLES) == before


def test_solve_says_what_it_ignores(api: Api) -> None:
    body = {
        "method": "xyz_npoint",
        "format": "xyz_wxyz",
        "activate": "always",
        "options": {"save_reference_point": "p"},
        "poses": as_poses(simulate_touches(8, seed=10)),
    }
    warnings = api.post("/v1/solve", body, scope="read").json()["warnings"]
    assert any("save_reference_point ignored" in w for w in warnings)
    assert any("activate 'always' ignored" in w for w in warnings)
