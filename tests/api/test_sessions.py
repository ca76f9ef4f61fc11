"""Planning and guided sessions over HTTP: the plan's poses touch the point, a simulated
operator follows `next_pose`, a missed touch is named and deleted, `finish` stores the
calibration as /calibrations would; bad touches leave the session as it was."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_from_format, pose_to_format
from tests.api.touches import row_counts
from tests.conftest import Api

TRUE_TCP = np.array([3.0, -2.0, 180.0])
POINT = np.array([820.0, 40.0, 260.0])
TOOL_DOWN = Rotation.from_euler("x", 180.0, degrees=True)


class Operator:
    """Moves to the suggested orientation and jogs until the real tip touches the point; the
    controller reports the flange with `noise_mm` per axis; some touches miss by 3 mm."""

    def __init__(self, seed: int, noise_mm: float, misses: dict[int, float]) -> None:
        self.rng = np.random.default_rng(seed)
        self.noise, self.misses, self.count = noise_mm, misses, 0

    def touch(self, rotation: np.ndarray) -> list[float]:
        f = POINT - rotation @ TRUE_TCP + self.rng.normal(0.0, self.noise, 3)
        if self.count in self.misses:
            d = self.rng.normal(size=3)
            f += self.misses[self.count] * d / np.linalg.norm(d)
        self.count += 1
        return _flat(pose_to_format("kuka_abc", rotation, f))


def _rotation(pose: Any) -> np.ndarray:
    return np.asarray(pose_from_format("kuka_abc", pose)[0])


def _flat(pose: list[float] | list[list[float]]) -> list[float]:
    assert all(isinstance(v, float) for v in pose)  # a flat format's pose
    return [float(v) for v in pose if isinstance(v, float)]


def _start_pose() -> list[float]:
    return _flat(
        pose_to_format("kuka_abc", TOOL_DOWN.as_matrix(), POINT - TOOL_DOWN.apply(TRUE_TCP))
    )


@pytest.fixture
def tool(api: Api) -> dict[str, Any]:
    robot = api.robot("kr16")
    return api.tool(robot["id"], "torch", tolerance={"max_rms_mm": 0.5, "max_residual_mm": 1.0})


def test_a_guided_session_names_the_miss_reaches_done_and_finishes(
    api: Api, tool: dict[str, Any]
) -> None:
    created = api.post(
        f"/v1/tools/{tool['id']}/sessions",
        json={
            "method": "xyz_npoint",
            "format": "kuka_abc",
            "target_sigma_mm": 0.05,
            "options": {"touch_noise_mm": 0.02},
        },
    )
    assert created.status_code == 201, created.text
    sid = created.json()["id"]
    assert created.json()["next_pose"] is None  # nothing to aim from before the first touch
    operator = Operator(seed=3, noise_mm=0.02, misses={2: 3.0})
    state = api.post(
        f"/v1/sessions/{sid}/poses", json={"pose": operator.touch(TOOL_DOWN.as_matrix())}
    ).json()
    named_at = None
    touches = 1
    while not state["done"]:
        assert touches < 12, state
        if state["outliers"]:
            named_at = named_at or touches
            assert state["outliers"] == [2], state  # touch #3
            assert any("touch 3 (index 2)" in m for m in state["messages"])
            state = api.delete(f"/v1/sessions/{sid}/poses/2").json()
            continue
        assert state["next_pose"] is not None
        state = api.post(
            f"/v1/sessions/{sid}/poses",
            json={"pose": operator.touch(_rotation(state["next_pose"]))},
        ).json()
        touches += 1
    assert named_at is not None, named_at
    assert named_at <= 6, named_at
    assert touches <= 12
    assert max(state["estimate"]["tcp_sigma_mm"]) <= 0.05
    assert state["next_pose"] is None

    finished = api.post(
        f"/v1/sessions/{sid}/finish", json={"note": "guided"}, headers={"Idempotency-Key": "fin-1"}
    )
    assert finished.status_code == 201, finished.text
    cal = finished.json()
    assert cal["status"] == "accepted"
    assert cal["version"] == 1
    assert cal["active"]
    error = np.abs(np.asarray(cal["tcp"]["position_mm"]) - TRUE_TCP)
    assert np.all(error <= 3 * np.asarray(cal["quality"]["tcp_sigma_mm"])), (error, cal["quality"])
    # Exactly as /calibrations: the request as received holds the kept touches.
    detail = api.get(f"/v1/calibrations/{cal['id']}").json()
    assert len(detail["request"]["poses"]) == state["n_poses"]
    assert detail["request"]["note"] == "guided"
    # A retry with the same key replays; without, a finished session refuses.
    again = api.post(
        f"/v1/sessions/{sid}/finish", json={"note": "guided"}, headers={"Idempotency-Key": "fin-1"}
    )
    assert again.status_code == 201
    assert again.json()["id"] == cal["id"]
    assert again.headers["Idempotent-Replayed"] == "true"
    assert api.post(f"/v1/sessions/{sid}/finish", json={}).status_code == 409
    late = api.post(f"/v1/sessions/{sid}/poses", json={"pose": _start_pose()})
    assert late.status_code == 409
    after = api.get(f"/v1/sessions/{sid}").json()
    assert after["status"] == "finished"
    assert after["calibration_id"] == cal["id"]


def test_bad_touches_are_refused_and_leave_the_session_as_it_was(
    api: Api, tool: dict[str, Any]
) -> None:
    sid = api.post(
        f"/v1/tools/{tool['id']}/sessions",
        json={"method": "xyz_npoint", "format": "kuka_abc", "target_sigma_mm": 0.001},
    ).json()["id"]
    operator = Operator(seed=4, noise_mm=0.02, misses={})
    state = api.post(
        f"/v1/sessions/{sid}/poses", json={"pose": operator.touch(TOOL_DOWN.as_matrix())}
    ).json()
    for _ in range(4):
        state = api.post(
            f"/v1/sessions/{sid}/poses",
            json={"pose": operator.touch(_rotation(state["next_pose"]))},
        ).json()
    before = api.get(f"/v1/sessions/{sid}").json()
    assert before["n_poses"] == 5
    assert before["estimate"] is not None

    good = operator.touch(_rotation(before["next_pose"]))
    cases = {
        "arity": (good[:5], 422),
        "sentinel": ([*good[:3], -3.7e28, *good[4:]], 422),
        "nan": ("nan", 422),
    }
    for name, (pose, status) in cases.items():
        body = '{"pose": [1, 2, NaN, 4, 5, 6]}' if pose == "nan" else None
        response = (
            api.client.post(
                f"/v1/sessions/{sid}/poses",
                content=body,
                headers={**api.headers(), "Content-Type": "application/json"},
            )
            if body
            else api.post(f"/v1/sessions/{sid}/poses", json={"pose": pose})
        )
        assert response.status_code == status, (name, response.text)
        assert response.headers["content-type"].startswith("application/problem+json")
        assert api.get(f"/v1/sessions/{sid}").json() == before, name
    # Degrees declared as radians: 180 "rad" is no angle a controller shows; the first touch
    # is refused and the session keeps nothing.
    as_rad = api.post(
        f"/v1/tools/{tool['id']}/sessions",
        json={"method": "xyz_npoint", "format": "kuka_abc", "units": {"angle": "rad"}},
    ).json()["id"]
    refused = api.post(f"/v1/sessions/{as_rad}/poses", json={"pose": before["poses"][0]})
    assert refused.status_code == 422
    assert api.get(f"/v1/sessions/{as_rad}").json()["n_poses"] == 0
    # Quaternions sent w-first to a session declared x-y-z-w: each touch reads as a rotation,
    # so the mix-up shows only once the set can be solved: the fourth touch is refused with
    # the reading that fits, and the session keeps the three before it.
    wrong = api.post(
        f"/v1/tools/{tool['id']}/sessions", json={"method": "xyz_npoint", "format": "xyz_xyzw"}
    ).json()["id"]
    statuses = []
    for pose in before["poses"][:4]:
        R, f = pose_from_format("kuka_abc", pose)
        sent = pose_to_format("xyz_wxyz", R, f)
        statuses.append(api.post(f"/v1/sessions/{wrong}/poses", json={"pose": sent}))
    assert [r.status_code for r in statuses] == [200, 200, 200, 422]
    problem = statuses[3].json()
    assert problem["type"].endswith("/convention-mismatch")
    assert problem["suggestion"]["format"] == "xyz_wxyz"
    assert api.get(f"/v1/sessions/{wrong}").json()["n_poses"] == 3

    assert api.get("/v1/sessions/00000000-0000-0000-0000-000000000000").status_code == 404
    assert api.delete(f"/v1/sessions/{sid}/poses/9").status_code == 404
    assert api.post("/v1/sessions/nope/poses", json={"pose": good}).status_code == 404
    counts = row_counts(("calibrations", "tcp_versions"))
    assert counts == {"calibrations": 0, "tcp_versions": 0}


def test_plan_poses_touch_the_point_and_beat_random_sets(api: Api) -> None:
    start = _start_pose()
    body = {
        "format": "kuka_abc",
        "start": start,
        "tcp_mm": list(TRUE_TCP),
        "touch_noise_mm": 0.02,
        "max_tilt_deg": 40,
        "max_spin_deg": 90,
        "n_poses": 6,
    }
    plan = api.post("/v1/plan", json=body)
    assert plan.status_code == 200, plan.text
    doc = plan.json()
    assert doc["n_poses"] == 6
    assert len(doc["poses"]) == 6
    assert api.post("/v1/plan", json=body).json() == doc  # deterministic
    down = TOOL_DOWN.apply([0.0, 0.0, 1.0])
    for pose in doc["poses"]:
        R, f = pose_from_format("kuka_abc", pose)
        assert np.allclose(np.asarray(R) @ TRUE_TCP + np.asarray(f), POINT, atol=1e-6)
        tilt = np.degrees(np.arccos(np.clip(np.asarray(R)[:, 2] @ down, -1, 1)))
        assert tilt <= 40.0 + 1e-6
    sigma = np.asarray(doc["predicted_tcp_sigma_mm"])
    assert doc["predicted_sigma_mm"] == pytest.approx(float(np.linalg.norm(sigma)))

    targeted = api.post(
        "/v1/plan",
        json={**{k: v for k, v in body.items() if k != "n_poses"}, "target_sigma_mm": 0.01},
    ).json()
    assert targeted["predicted_sigma_mm"] <= 0.01
    fewer = api.post("/v1/plan", json={**body, "n_poses": targeted["n_poses"] - 1}).json()
    assert fewer["predicted_sigma_mm"] > 0.01  # the smallest N that reaches the target
    unreachable = api.post(
        "/v1/plan",
        json={**{k: v for k, v in body.items() if k != "n_poses"}, "target_sigma_mm": 0.001},
    )
    assert unreachable.status_code == 422
    problem = unreachable.json()
    assert problem["errors"][0]["loc"] == ["body", "target_sigma_mm"]
    assert problem["best_sigma_mm"] > 0.001
    assert f"{problem['best_sigma_mm']:.4f}" in problem["detail"]
    both = api.post("/v1/plan", json={**body, "target_sigma_mm": 0.01})
    assert both.status_code == 422
    flat = api.post("/v1/plan", json={**body, "max_tilt_deg": 0, "max_spin_deg": 0})
    assert flat.status_code == 422


def test_each_read_gives_the_residuals_and_the_next_touch_in_words(
    api: Api, tool: dict[str, Any]
) -> None:
    """The console shows each touch's residual and says the suggested touch in words: the
    tilt of the tool axis from the first touch's, where it leans, and the spin about it."""
    body = {"method": "xyz_npoint", "format": "kuka_abc", "target_sigma_mm": 0.01}
    sid = api.post(f"/v1/tools/{tool['id']}/sessions", json=body).json()["id"]
    operator = Operator(seed=5, noise_mm=0.02, misses={})
    state = api.post(
        f"/v1/sessions/{sid}/poses", json={"pose": operator.touch(TOOL_DOWN.as_matrix())}
    ).json()
    assert state["residuals_mm"] is None  # no estimate from one touch
    for _ in range(5):
        first, suggested = _rotation(state["poses"][0]), _rotation(state["next_pose"])
        words = state["next_touch"]
        # independently: the tool axes' angle, the lean in the first flange's x-y, and the
        # rotation rebuilt as a tilt about an axis in that plane followed by the spin
        axis = suggested[:, 2]
        tilt = np.degrees(np.arccos(np.clip(first[:, 2] @ axis, -1.0, 1.0)))
        assert words["tilt_deg"] == pytest.approx(tilt, abs=1e-6)
        assert words["tilt_deg"] > 1.0  # a suggestion is another orientation
        lean = np.degrees(np.arctan2(first[:, 1] @ axis, first[:, 0] @ axis)) % 360.0
        assert words["lean_deg"] == pytest.approx(lean, abs=1e-6)
        swing_axis = np.radians(words["lean_deg"] + 90.0)
        rebuilt = Rotation.from_rotvec(
            np.radians(words["tilt_deg"]) * np.array([np.cos(swing_axis), np.sin(swing_axis), 0])
        ) * Rotation.from_euler("z", words["spin_deg"], degrees=True)
        off = rebuilt.inv() * Rotation.from_matrix(first.T @ suggested)
        assert np.degrees(off.magnitude()) < 1e-6, words
        assert -180.0 <= words["spin_deg"] <= 180.0
        state = api.post(
            f"/v1/sessions/{sid}/poses", json={"pose": operator.touch(suggested)}
        ).json()
    assert state["n_poses"] == 6
    residuals = state["residuals_mm"]
    assert residuals is not None
    assert len(residuals) == 6
    cal = api.post(f"/v1/sessions/{sid}/finish", json={"activate": "never"}).json()
    np.testing.assert_allclose(residuals, cal["quality"]["residuals_mm"], atol=1e-12)
    assert max(residuals) == pytest.approx(cal["quality"]["max_mm"], abs=1e-12)
    after = api.get(f"/v1/sessions/{sid}").json()
    assert after["next_pose"] is None
    assert after["next_touch"] is None


def test_a_touch_is_read_in_the_sessions_format_and_a_declared_other_one_is_refused(
    api: Api, tool: dict[str, Any]
) -> None:
    """A session's format is the session's (issue 51, defect 2): a touch may say which format
    it is in (`format`), and one that names another is refused at body.format, naming both,
    never read as the session's; the session keeps nothing. An empty session asked to drop
    a touch says it holds none (it said "touches 1 to 0, indices 0 to -1")."""
    sid = api.post(
        f"/v1/tools/{tool['id']}/sessions", json={"method": "xyz_npoint", "format": "techman_rxyz"}
    ).json()["id"]
    pose = [887.5, 18.251, 568.212, 0.0, 0.0, -155.0]
    other = api.post(f"/v1/sessions/{sid}/poses", json={"pose": pose, "format": "kuka_abc"})
    assert other.status_code == 422, other.text
    problem = other.json()
    assert other.headers["content-type"].startswith("application/problem+json")
    assert problem["errors"][0]["loc"] == ["body", "format"]
    assert problem["type"].endswith("/invalid-pose")  # the session refuses it, not the schema
    assert problem["detail"] == (
        f"session {sid} reads its poses as techman_rxyz, not kuka_abc: send the pose as "
        "techman_rxyz (a touch is never converted), or start a session in kuka_abc"
    )
    assert api.get(f"/v1/sessions/{sid}").json()["n_poses"] == 0
    # a frame touch's field on a tool session: refused by the session, named (the schema of
    # the route takes either touch; schemathesis: schema_valid_is_not_refused_by_the_schema)
    framed = api.post(f"/v1/sessions/{sid}/poses", json={"capture": True, "nominal_mm": None})
    assert framed.status_code == 422, framed.text
    assert framed.json()["type"].endswith("/invalid-pose"), framed.text
    assert framed.json()["errors"][0]["loc"] == ["body", "nominal_mm"]
    assert "belong to a frame's session's touches" in framed.json()["detail"]
    empty = api.delete(f"/v1/sessions/{sid}/poses/0")
    assert empty.status_code == 404
    assert empty.json()["detail"] == f"session {sid} holds no touches yet: there is none to delete"

    same = api.post(f"/v1/sessions/{sid}/poses", json={"pose": pose, "format": "techman_rxyz"})
    assert same.status_code == 200, same.text
    assert same.json()["poses"] == [pose]
    past = api.delete(f"/v1/sessions/{sid}/poses/1")
    assert "it holds 1 (touch 1, index 0; touch n is index n - 1)" in past.json()["detail"]
