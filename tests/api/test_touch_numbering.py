"""One numbering for people: a set whose fifth touch misses is "touch 5" in the solver's
warning, the summary and the session's messages; the index fields stay 0-based (index 4)."""

from __future__ import annotations

from app.solvers.npoint import solve_npoint
from app.solvers.numbering import numbered
from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses
from tests.conftest import Api


def _fifth_missed(n: int = 8) -> list[list[float]]:
    touches = simulate_touches(n, seed=11, touch_noise_mm=0.02)
    poses = as_poses(touches)
    poses[4][0] += 3.0  # the fifth touch, index 4, misses by 3 mm
    return poses


def test_numbered_names_touches_from_one() -> None:
    assert numbered("touch", [4]) == "touch 5"
    assert numbered("touch", [0, 4, 6]) == "touches 1, 5 and 7"
    assert numbered("pose", [1, 2]) == "poses 2 and 3"


def test_solver_warning_names_the_fifth_touch_5() -> None:
    touches = simulate_touches(8, seed=11, touch_noise_mm=0.02)
    f = touches.f.copy()
    f[4, 0] += 3.0
    result = solve_npoint(touches.R, f)
    assert list(result.quality.outliers) == [4]
    [warning] = [w for w in result.quality.warnings if "set aside" in w]
    assert "touch 5 (" in warning, warning
    assert "touch 4" not in warning


def test_summary_and_warnings_of_a_calibration_say_touch_5(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "torch", slot=1)
    response = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": _fifth_missed()},
        scope="calibrate",
    )
    assert response.status_code == 201, response.text
    result = response.json()
    assert result["quality"]["outliers"] == [4]  # the index field stays 0-based
    assert "touch 5 set aside" in result["summary"], result["summary"]
    assert any("touch 5 (" in w for w in result["warnings"]), result["warnings"]
    sentences = [result["summary"], *result["warnings"]]
    assert not any("touch 4" in s or "#" in s for s in sentences), sentences


def test_session_messages_say_touch_5_and_keep_index_4(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "torch", slot=1)
    session = api.post(
        f"/v1/tools/{tool['id']}/sessions",
        {"method": "xyz_npoint", "format": "xyz_wxyz", "options": {"touch_noise_mm": 0.02}},
        scope="calibrate",
    ).json()
    state = session
    for pose in _fifth_missed(9):
        response = api.post(
            f"/v1/sessions/{session['id']}/poses", {"pose": pose}, scope="calibrate"
        )
        assert response.status_code == 200, response.text
        state = response.json()
    assert state["outliers"] == [4], state
    assert any("touch 5 (index 4)" in m for m in state["messages"]), state["messages"]
    missing = api.delete(f"/v1/sessions/{session['id']}/poses/9", scope="calibrate")
    assert missing.status_code == 404
    assert "touches 1 to 9" in missing.json()["detail"]


def test_pose_refusals_count_from_one(api: Api) -> None:
    poses = _fifth_missed()
    poses[2] = [*poses[2][:3], 2.0, 0.0, 0.0, 0.0]  # the third pose: not a unit quaternion
    robot = api.robot("kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "torch", slot=1)
    response = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": poses},
        scope="calibrate",
    )
    assert response.status_code == 422
    problem = response.json()
    assert problem["detail"].startswith("pose 3:"), problem["detail"]
    assert problem["errors"][0]["loc"][:3] == ["body", "poses", 2]


def test_a_bad_session_touch_is_named_by_its_number_at_body_pose(api: Api) -> None:
    """The fourth touch sent to a session is pose 4 in the sentence, and its loc is the body's
    one `pose` (no list index: the body holds one pose)."""
    robot = api.robot("kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "torch", slot=1)
    session = api.post(
        f"/v1/tools/{tool['id']}/sessions",
        {"method": "xyz_npoint", "format": "xyz_wxyz"},
        scope="calibrate",
    ).json()
    poses = _fifth_missed()
    for pose in poses[:3]:
        kept = api.post(f"/v1/sessions/{session['id']}/poses", {"pose": pose}, scope="calibrate")
        assert kept.status_code == 200, kept.text
    bad = [*poses[3][:3], 2.0, 0.0, 0.0, 0.0]  # not a unit quaternion
    refused = api.post(f"/v1/sessions/{session['id']}/poses", {"pose": bad}, scope="calibrate")
    assert refused.status_code == 422, refused.text
    problem = refused.json()
    assert problem["detail"].startswith("pose 4:"), problem["detail"]
    assert problem["errors"][0]["loc"] == ["body", "pose", "quaternion"], problem["errors"]
    assert problem["errors"][0]["msg"].startswith("pose 4:"), problem["errors"]
    far = [-3.7e28, *poses[3][1:]]
    refused = api.post(f"/v1/sessions/{session['id']}/poses", {"pose": far}, scope="calibrate")
    assert refused.json()["detail"].startswith("pose 4: coordinate x"), refused.text
    assert refused.json()["errors"][0]["loc"][:3] == ["body", "pose", "position"]
    assert len(api.get(f"/v1/sessions/{session['id']}").json()["poses"]) == 3


def test_a_bad_reference_touch_is_located_at_its_one_pose(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    api.manual(tool["id"], [0, 0, 100])
    touch = {"tool_id": tool["id"], "format": "xyz_wxyz", "pose": [500, 0, 400, 2, 0, 0, 0]}
    refused = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "pin", "touch": touch},
        scope="calibrate",
    )
    assert refused.status_code == 422, refused.text
    problem = refused.json()
    assert problem["detail"].startswith("pose 1:"), problem["detail"]
    assert problem["errors"][0]["loc"] == ["body", "touch", "pose", "quaternion"]
