"""xyz_plane over HTTP: every pose format, labelled planes, refusals, diagnosis and sessions."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_to_format
from testbed.sim.planes import PlaneTouches, simulate_plane_touches
from testbed.sim.touches import TOOL_DOWN
from tests.api.touches import row_counts, within
from tests.conftest import TABLES, Api

FORMATS = ["matrix", "xyz_wxyz", "xyz_xyzw", "kuka_abc", "fanuc_wpr", "ur_rotvec"]


def _poses(sim: PlaneTouches, fmt: str, units: dict[str, str] | None = None) -> list[Any]:
    return [pose_to_format(fmt, R, f, units=units) for R, f in zip(sim.R, sim.f, strict=True)]


def _labelled(sim: PlaneTouches, fmt: str) -> list[Any]:
    return [
        {"plane": label, "pose": pose}
        for label, pose in zip(sim.labels, _poses(sim, fmt), strict=True)
    ]


def _tool(api: Api) -> str:
    return str(api.tool(api.robot()["id"])["id"])


def test_plane_touches_in_every_format_give_the_same_tcp(api: Api) -> None:
    sim = simulate_plane_touches(10, seed=21, tilt_deg=40.0, touch_noise_mm=0.02)
    tcps = {}
    for fmt in FORMATS:
        response = api.post(
            "/v1/solve", {"method": "xyz_plane", "format": fmt, "poses": _poses(sim, fmt)}
        )
        assert response.status_code == 200, (fmt, response.text)
        body = response.json()
        assert body["method"] == "xyz_plane"
        assert body["status"] == "accepted"
        tcps[fmt] = body["tcp"]["position_mm"]
        assert within(body["tcp"]["position_mm"], sim.t, body["quality"]["tcp_sigma_mm"])
    for fmt, tcp in tcps.items():
        assert np.allclose(tcp, tcps["matrix"], atol=1e-6), fmt


def test_a_stored_plane_calibration_reports_the_plane_and_its_geometry(api: Api) -> None:
    sim = simulate_plane_touches(10, seed=22, tilt_deg=40.0, touch_noise_mm=0.02)
    tool = _tool(api)
    response = api.post(
        f"/v1/tools/{tool}/calibrations",
        {"method": "xyz_plane", "format": "kuka_abc", "poses": _poses(sim, "kuka_abc")},
        scope="calibrate",
    )
    assert response.status_code == 201, response.text
    out = response.json()
    assert (out["status"], out["version"], out["active"]) == ("accepted", 1, True)
    assert out["reference_point_mm"] is None
    details = out["details"]
    (plane,) = details["planes"]
    assert plane["label"] == "a"
    assert plane["n_touches"] == 10
    assert abs(abs(np.dot(plane["normal"], sim.normals[0])) - 1.0) < 1e-4
    assert details["touch_planes"] == ["a"] * 10
    assert len(details["tcp_sigma_tool_mm"]) == 3
    assert out["quality"]["sigma_source"] == "residuals"
    assert out["summary"]
    detail = api.get(f"/v1/calibrations/{out['id']}").json()
    assert len(detail["geometry"]["tip_positions_mm"]) == 10
    assert detail["details"] == details


def test_labelled_planes_share_one_tcp(api: Api) -> None:
    sim = simulate_plane_touches(15, seed=23, planes=3, tilt_deg=40.0, touch_noise_mm=0.02)
    tool = _tool(api)
    body = {
        "method": "xyz_plane",
        "format": "xyz_wxyz",
        "poses": _labelled(sim, "xyz_wxyz"),
        "options": {"planes": ["a", "b", "c"]},
    }
    response = api.post(f"/v1/tools/{tool}/calibrations", body, scope="calibrate")
    assert response.status_code == 201, response.text
    out = response.json()
    assert [p["label"] for p in out["details"]["planes"]] == ["a", "b", "c"]
    assert out["details"]["touch_planes"] == sim.labels
    assert within(out["tcp"]["position_mm"], sim.t, out["quality"]["tcp_sigma_mm"])
    # the stored request is read back with its labels (the report's 3-D view)
    detail = api.get(f"/v1/calibrations/{out['id']}").json()
    assert detail["request"]["poses"][0]["plane"] == "a"
    assert len(detail["geometry"]["flange_positions_mm"]) == 15


@pytest.mark.parametrize(
    ("change", "loc", "words"),
    [
        (lambda b: b["options"].pop("planes"), ["body", "poses", 0, "plane"], "options.planes"),
        (lambda b: b["poses"].__setitem__(4, b["poses"][4]["pose"]), ["body", "poses", 4], "say"),
        (
            lambda b: b["options"].__setitem__("planes", ["a", "b"]),
            ["body", "poses", 2, "plane"],
            "'c'",
        ),
        (lambda b: b["options"].__setitem__("planes", ["a", "b", "c", "c"]), None, None),
        (lambda b: b["poses"][3].__setitem__("plane", "d"), ["body", "poses", 3, "plane"], None),
    ],
)
def test_labels_that_do_not_match_the_planes_are_refused(
    api: Api, change: Any, loc: list[Any] | None, words: str | None
) -> None:
    sim = simulate_plane_touches(15, seed=24, planes=3, tilt_deg=40.0)
    body: dict[str, Any] = {
        "method": "xyz_plane",
        "format": "matrix",
        "poses": _labelled(sim, "matrix"),
        "options": {"planes": ["a", "b", "c"]},
    }
    change(body)
    before = row_counts(TABLES)
    response = api.post(f"/v1/tools/{_tool(api)}/calibrations", body, scope="calibrate")
    assert response.status_code == 422, response.text
    problem = response.json()
    if loc is not None:
        assert problem["errors"][0]["loc"] == loc, problem
    if words is not None:
        assert words in problem["detail"], problem
    assert row_counts(TABLES)["calibrations"] == before["calibrations"]


def test_parallel_tool_axes_are_refused_naming_what_to_vary(api: Api) -> None:
    spins = Rotation.from_euler("z", np.linspace(-150, 150, 8)[:, None], degrees=True)
    R = ((Rotation.from_euler("y", 20, degrees=True) * TOOL_DOWN) * spins).as_matrix()
    rng = np.random.default_rng(0)
    points = np.column_stack(
        [rng.uniform(700, 900, 8), rng.uniform(-250, -50, 8), np.full(8, 250.0)]
    )
    f = points - R @ np.array([0.0, 0.0, 150.0])
    poses = [pose_to_format("kuka_abc", r, p) for r, p in zip(R, f, strict=True)]
    response = api.post("/v1/solve", {"method": "xyz_plane", "format": "kuka_abc", "poses": poses})
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"].endswith("/degenerate-poses")
    assert "parallel tool axes" in problem["detail"]
    assert "tilt the tool about another axis" in problem["detail"]


def test_six_touches_are_refused_with_what_to_send(api: Api) -> None:
    sim = simulate_plane_touches(6, seed=25)
    response = api.post(
        "/v1/solve", {"method": "xyz_plane", "format": "matrix", "poses": _poses(sim, "matrix")}
    )
    assert response.status_code == 422
    problem = response.json()
    assert problem["type"].endswith("/too-few-poses")
    assert "7 or more points" in problem["detail"]


def test_metres_sent_as_millimetres_are_named(api: Api) -> None:
    """The convention diagnosis runs for plane touches as for every method."""
    sim = simulate_plane_touches(10, seed=26, tilt_deg=40.0, touch_noise_mm=0.02)
    poses = _poses(sim, "kuka_abc", units={"length": "m"})
    response = api.post("/v1/solve", {"method": "xyz_plane", "format": "kuka_abc", "poses": poses})
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"].endswith("/convention-mismatch")
    assert problem["suggestion"]["units"]["length"] == "m"


def test_guided_sessions_say_they_do_not_guide_plane_touches(api: Api) -> None:
    response = api.post(
        f"/v1/tools/{_tool(api)}/sessions",
        {"method": "xyz_plane", "format": "kuka_abc"},
        scope="calibrate",
    )
    assert response.status_code == 422
    problem = response.json()
    assert "xyz_npoint" in problem["detail"]
    assert "xyz_plane" in problem["detail"]
    assert problem["errors"][0]["loc"] == ["body", "method"]


def test_methods_lists_xyz_plane(api: Api) -> None:
    items = {m["name"]: m for m in api.get("/v1/methods").json()["items"]}
    plane = items["xyz_plane"]
    assert plane["min_poses"] == 7
    assert set(plane["options"]) == {"planes", "touch_noise_mm"}
