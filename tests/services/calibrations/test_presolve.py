"""A calibration solved before its transaction is stored as solved only if what the solve read
(tolerance, active version, robot model) is unchanged at the lock; otherwise it is solved
again there, so the stored result never rests on a stale active TCP."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from app.errors import Archived, NotFound
from app.methods.requests import CALIBRATION_REQUESTS
from app.security.auth import Principal
from app.services.calibrations import presolve, writes
from app.services.calibrations.presolve import Presolved
from app.storage.db import get_engine, session_scope
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses
from tests.conftest import Api

ACTOR = Principal(key_id="test", name="test", scope="admin")


def _manual(api: Api, tool_id: str, tcp: list[float]) -> None:
    api.post(
        f"/v1/tools/{tool_id}/calibrations",
        json={"method": "manual", "tcp": {"position_mm": tcp}},
    )


def test_a_stale_presolve_is_solved_again_under_the_lock(api: Api) -> None:
    tool = api.tool(api.robot("kr")["id"])
    tid = tool["id"]
    touches = simulate_touches(8, seed=2, tcp_mm=None)
    _manual(api, tid, [*map(float, touches.t[:2]), float(touches.t[2]) + 1.0])  # 1 mm off
    body: dict[str, Any] = {
        "method": "xyz_npoint",
        "format": "kuka_abc",
        "poses": as_poses(touches, "kuka_abc"),
        "activate": "never",
    }
    request = CALIBRATION_REQUESTS.validate_python(body)
    snapshot, ctx = presolve.snapshot_held(get_engine(), tid)
    outcome = presolve.solve_snapshot(request, ctx)
    assert outcome is not None
    before = outcome.result.change_from_active_mm
    assert before is not None
    assert abs(before - 1.0) < 0.2

    _manual(api, tid, [*map(float, touches.t[:2]), float(touches.t[2]) + 3.0])  # now v2
    with session_scope(write=True) as session:
        stored, _ = writes.submit(
            session, tool_id=tid, request=request, raw_body=body, idempotency_key=None,
            actor=ACTOR, solved=Presolved(snapshot, outcome),
        )  # fmt: skip
    assert stored.change_from_active_mm is not None
    assert abs(stored.change_from_active_mm - 3.0) < 0.2  # against version 2, not 1

    snapshot, ctx = presolve.snapshot_held(get_engine(), tid)
    fresh = presolve.solve_snapshot(request, ctx)
    assert fresh is not None
    with session_scope(write=True) as session:
        kept, _ = writes.submit(
            session, tool_id=tid, request=request, raw_body=body, idempotency_key=None,
            actor=ACTOR, solved=Presolved(snapshot, fresh),
        )  # fmt: skip
    assert kept.model_dump(exclude={"id", "version", "created_at"}) == {
        **fresh.result.model_dump(), "tool_id": tid, "active": False, "created_by": "test"
    }  # fmt: skip


def test_methods_that_look_up_stored_data_are_solved_in_place(api: Api) -> None:
    robot = api.robot("kr2")
    tool = api.tool(robot["id"])
    point = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        json={"name": "pin", "position_mm": [800, 0, 250]},
    ).json()
    body = {"method": "xyz_reference", "format": "kuka_abc",
            "poses": [[800, 0, 400, 0, 0, 180]],
            "options": {"reference_point_id": point["id"]}}  # fmt: skip
    request = CALIBRATION_REQUESTS.validate_python(body)
    _, ctx = presolve.snapshot_held(get_engine(), tool["id"])
    assert presolve.solve_snapshot(request, ctx) is None
    done = api.post(f"/v1/tools/{tool['id']}/calibrations", json=body)
    assert done.status_code == 201, done.text


def test_the_held_snapshot_reads_the_active_frame_with_its_reported_covariance(api: Api) -> None:
    tool = api.tool(api.robot("kr3")["id"])
    tid = tool["id"]
    _, ctx = presolve.snapshot_held(get_engine(), tid)
    assert ctx.active_frame() is None  # no version yet
    touches = simulate_touches(8, seed=4, tcp_mm=None, touch_noise_mm=0.05)
    done = api.post(
        f"/v1/tools/{tid}/calibrations",
        json={"method": "xyz_npoint", "format": "kuka_abc", "poses": as_poses(touches, "kuka_abc"),
              "activate": "always"},
    )  # fmt: skip
    assert done.status_code == 201, done.text
    result = done.json()
    snapshot, ctx = presolve.snapshot_held(get_engine(), tid)
    frame = ctx.active_frame()
    assert frame is not None
    assert snapshot.active_version == frame.version == result["version"]
    np.testing.assert_allclose(frame.position_mm, result["tcp"]["position_mm"])
    np.testing.assert_allclose(frame.quaternion, result["tcp"]["quaternion"])
    assert frame.covariance_mm2 is not None
    np.testing.assert_allclose(frame.covariance_mm2, result["quality"]["tcp_covariance_mm2"])
    with pytest.raises(NotFound):
        presolve.snapshot_held(get_engine(), "no-such-tool")
    assert api.delete(f"/v1/tools/{tid}").status_code == 204
    with pytest.raises(Archived):
        presolve.snapshot_held(get_engine(), tid)
