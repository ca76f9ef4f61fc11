"""A unit or convention mix-up is refused with the reading that fits, never graded.

Each case writes the same simulated touches under one reading and sends them as another.
The answer must be 422 `convention-mismatch` naming the reading they were written in, with
no row written anywhere; resent as suggested they solve to the true TCP.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from app.jsontypes import JsonObject
from app.kinematics.poses import pose_to_format
from testbed.sim.touches import Touches, simulate_touches
from tests.api.touches import row_counts, within
from tests.conftest import TABLES, Api

MISMATCH = "application/problem+json"

# (case, format written, units written, format sent, units sent)
MIX_UPS = [
    ("metres as mm, xyz_wxyz", "xyz_wxyz", {"length": "m"}, "xyz_wxyz", None),
    ("metres as mm, xyz_xyzw", "xyz_xyzw", {"length": "m"}, "xyz_xyzw", None),
    ("metres as mm, kuka_abc", "kuka_abc", {"length": "m"}, "kuka_abc", None),
    ("radians as degrees, kuka_abc", "kuka_abc", {"angle": "rad"}, "kuka_abc", None),
    ("radians as degrees, fanuc_wpr", "fanuc_wpr", {"angle": "rad"}, "fanuc_wpr", None),
    ("degrees as radians, ur_rotvec", "ur_rotvec", {"angle": "deg"}, "ur_rotvec", None),
    ("millimetres as metres, ur_rotvec", "ur_rotvec", {"length": "mm"}, "ur_rotvec", None),
    ("xyzw sent as wxyz", "xyz_xyzw", None, "xyz_wxyz", None),
    ("UR RPY sent as a rotation vector", "fanuc_wpr", {"length": "m", "angle": "rad"},
     "ur_rotvec", None),
    ("KUKA ABC sent as Fanuc WPR", "kuka_abc", None, "fanuc_wpr", None),
    ("units override wrong: mm said to be m", "kuka_abc", None, "kuka_abc", {"length": "m"}),
]  # fmt: skip
DEFAULTS = {"ur_rotvec": {"length": "m", "angle": "rad"}}


def _poses(touches: Touches, fmt: str, units: dict[str, str] | None) -> list[Any]:
    return [
        pose_to_format(fmt, R, f, units=units) for R, f in zip(touches.R, touches.f, strict=True)
    ]


def _pin_and_touches(
    api: Api, robot: JsonObject, tool: JsonObject, n: int, fmt: str, units: dict[str, str]
) -> tuple[JsonObject, list[Any]]:
    """`tool` given an active TCP of (0, 0, 150) mm, a reference point "pin" on `robot`, and n
    exact touches of it written in `fmt` with `units`."""
    tcp = np.array([0.0, 0.0, 150.0])
    api.manual(tool["id"], tcp.tolist())
    pin = np.array([650.0, 80.0, 210.0])
    point = api.post(
        f"/v1/robots/{robot['id']}/reference-points",
        {"name": "pin", "position_mm": pin.tolist()},
        scope="calibrate",
    ).json()
    touches = simulate_touches(n, seed=5, touch_noise_mm=0.0, tcp_mm=tcp, pivot_mm=pin)
    return point, _poses(touches, fmt, units)


def _written_as(fmt: str, units: dict[str, str] | None) -> JsonObject:
    full = {"length": "mm", "angle": "deg", **DEFAULTS.get(fmt, {}), **(units or {})}
    return {"format": fmt, "units": full}


def _same_reading(suggestion: JsonObject, expected: JsonObject) -> bool:
    """Equal where it matters: quaternion formats have no angles to read."""
    if suggestion["format"] != expected["format"]:
        return False
    keys = ("length",) if expected["format"] in ("xyz_wxyz", "xyz_xyzw") else ("length", "angle")
    return all(suggestion["units"][k] == expected["units"][k] for k in keys)


@pytest.fixture
def tool_id(api: Api) -> str:
    robot = api.robot("kr16")
    return str(api.tool(robot["id"], "torch", slot=3)["id"])


@pytest.mark.parametrize(("case", "written", "written_units", "sent", "sent_units"), MIX_UPS)
def test_mix_up_is_refused_with_the_reading_that_fits_and_nothing_is_stored(
    api: Api,
    tool_id: str,
    case: str,
    written: str,
    written_units: dict[str, str] | None,
    sent: str,
    sent_units: dict[str, str] | None,
) -> None:
    touches = simulate_touches(8, seed=21, touch_noise_mm=0.05)
    body: JsonObject = {
        "method": "xyz_npoint",
        "format": sent,
        "poses": _poses(touches, written, written_units),
    }
    if sent_units:
        body["units"] = sent_units
    before = row_counts(TABLES)
    response = api.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate")

    assert response.status_code == 422, (case, response.text)
    assert response.headers["content-type"].startswith(MISMATCH)
    problem = response.json()
    assert problem["type"].endswith("/convention-mismatch"), problem
    assert _same_reading(problem["suggestion"], _written_as(written, written_units)), problem
    if problem["suggestion"]["format"] in ("xyz_wxyz", "xyz_xyzw"):
        # A quaternion has no angles: a suggested angle unit would read as if it mattered.
        assert set(problem["suggestion"]["units"]) == {"length"}
        assert "'angle'" not in problem["detail"]
    assert problem["rms_as_suggested_mm"] < 0.2
    given = problem["rms_as_given_mm"]
    assert given is None or given > 10 * problem["rms_as_suggested_mm"] or given < 0.01
    assert "Resend with format" in problem["detail"]
    assert problem["errors"][0]["loc"] == ["body", "format"]
    assert row_counts(TABLES) == before

    resent = api.post(
        f"/v1/tools/{tool_id}/calibrations", {**body, **problem["suggestion"]}, scope="calibrate"
    )
    assert resent.status_code == 201, resent.text
    cal = resent.json()
    assert cal["status"] == "accepted"
    assert within(cal["tcp"]["position_mm"], touches.t, cal["quality"]["tcp_sigma_mm"], k=3.0)


def test_stateless_solve_refuses_a_mix_up_too(api: Api) -> None:
    touches = simulate_touches(8, seed=4, touch_noise_mm=0.05)
    body = {
        "method": "xyz_npoint",
        "format": "kuka_abc",
        "poses": _poses(touches, "kuka_abc", {"angle": "rad"}),
    }
    response = api.post("/v1/solve", body, scope="read")
    assert response.status_code == 422, response.text
    assert response.json()["suggestion"] == {
        "format": "kuka_abc",
        "units": {"length": "mm", "angle": "rad"},
    }


@pytest.mark.parametrize("fmt", ["xyz_wxyz", "kuka_abc", "fanuc_wpr", "ur_rotvec", "matrix"])
def test_correct_noisy_submission_with_a_missed_touch_is_not_refused(
    api: Api, tool_id: str, fmt: str
) -> None:
    touches = simulate_touches(
        10, seed=8, touch_noise_mm=0.1, outlier_fraction=0.1 + 1e-9, outlier_mm=4.0
    )
    body = {"method": "xyz_npoint", "format": fmt, "poses": _poses(touches, fmt, None)}
    response = api.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate")
    assert response.status_code == 201, response.text
    cal = response.json()
    assert cal["status"] == "accepted"
    assert cal["quality"]["outliers"] == [int(i) for i in np.flatnonzero(touches.outliers)]


def test_correct_but_too_noisy_submission_is_graded_not_blamed_on_the_convention(
    api: Api, tool_id: str
) -> None:
    touches = simulate_touches(8, seed=9, touch_noise_mm=0.8)
    body = {
        "method": "xyz_npoint",
        "format": "kuka_abc",
        "poses": _poses(touches, "kuka_abc", None),
    }
    response = api.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate")
    assert response.status_code == 201, response.text
    assert response.json()["status"] == "out_of_tolerance"


def test_metres_as_mm_that_no_reading_fits_is_refused_never_accepted(
    api: Api, tool_id: str
) -> None:
    # Noise far above the tolerance: no reading fits, but read as mm the flange sits at the
    # robot base and the tiny rms would look excellent.
    touches = simulate_touches(8, seed=9, touch_noise_mm=0.8)
    body = {
        "method": "xyz_npoint",
        "format": "xyz_wxyz",
        "poses": _poses(touches, "xyz_wxyz", {"length": "m"}),
    }
    before = row_counts(TABLES)
    response = api.post(f"/v1/tools/{tool_id}/calibrations", body, scope="calibrate")
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"].endswith("/out-of-range")
    assert "within 20 mm of the robot base origin" in problem["detail"]
    assert "units {'length': 'm'}" in problem["detail"]
    # It said "not in millimetres (metres?)" and then "no other reading fits": it now says
    # what the metres reading gave, so the two do not read as a contradiction.
    assert "cannot be millimetres; read as metres they fit only to rms" in problem["detail"]
    assert row_counts(TABLES) == before


def test_check_with_radians_sent_as_degrees_is_refused_and_not_recorded(api: Api) -> None:
    robot = api.robot("kr16")
    tool = api.tool(robot["id"], "torch", slot=3)
    point, poses = _pin_and_touches(api, robot, tool, 3, "kuka_abc", {"angle": "rad"})
    body = {"reference_point_id": point["id"], "format": "kuka_abc", "poses": poses}
    before = row_counts(TABLES)
    response = api.post(f"/v1/tools/{tool['id']}/checks", body, scope="calibrate")
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"].endswith("/convention-mismatch")
    assert problem["suggestion"] == {
        "format": "kuka_abc",
        "units": {"length": "mm", "angle": "rad"},
    }
    assert problem["rms_as_suggested_mm"] < 1e-6
    assert row_counts(TABLES) == before

    resent = api.post(
        f"/v1/tools/{tool['id']}/checks", {**body, **problem["suggestion"]}, scope="calibrate"
    )
    assert resent.status_code == 200, resent.text
    assert resent.json()["within_tolerance"] is True


def test_reference_touch_in_metres_is_refused_with_the_reading_in_metres(api: Api) -> None:
    robot = api.robot("kr16")
    tool = api.tool(robot["id"], "torch", slot=3)
    api.manual(tool["id"], [0, 0, 100])
    # KUKA pose of the flange at (0.5, 0, 0.4) m, tool down: one touch, no residual to
    # judge; the flange "at the robot base" read as mm is what tells.
    pose = [0.5, 0.0, 0.4, 0.0, 0.0, 180.0]
    touch: JsonObject = {"tool_id": tool["id"], "format": "kuka_abc", "pose": pose}
    body: JsonObject = {"name": "pin", "touch": touch}
    before = row_counts(TABLES)
    response = api.post(f"/v1/robots/{robot['id']}/reference-points", body, scope="calibrate")
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"].endswith("/convention-mismatch")
    assert problem["suggestion"] == {"format": "kuka_abc", "units": {"length": "m", "angle": "deg"}}
    assert problem["errors"][0]["loc"] == ["body", "touch", "format"]
    assert row_counts(TABLES) == before

    body["touch"] = {**touch, **problem["suggestion"]}
    created = api.post(f"/v1/robots/{robot['id']}/reference-points", body, scope="calibrate")
    assert created.status_code == 201, created.text
    assert np.allclose(created.json()["position_mm"], [500, 0, 300], atol=1e-6)


@pytest.mark.parametrize("method", ["xyz_reference", "abc_2point", "abc_world", "laser_beam"])
def test_every_pose_method_refuses_metres_sent_as_millimetres(api: Api, method: str) -> None:
    """Single-touch methods have no residual to judge by; where the flange is still tells."""
    from app.methods import METHODS_BY_NAME

    example = METHODS_BY_NAME[method].example
    poses = [[v / 1000 if i < 3 else v for i, v in enumerate(p)] for p in example["poses"]]
    body = {**example, "poses": poses}
    response = api.post("/v1/solve", body, scope="read")
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"].endswith("/convention-mismatch"), problem
    assert problem["suggestion"]["units"]["length"] == "m"
    resent = api.post("/v1/solve", {**body, **problem["suggestion"]}, scope="read")
    assert resent.status_code == 200, resent.text
    solved = api.post("/v1/solve", example, scope="read").json()
    assert np.allclose(resent.json()["tcp"]["position_mm"], solved["tcp"]["position_mm"], atol=1e-6)


#: A UR pendant's rotation vector in degrees, sent as the format's default radians: read as
#: given the rotations are out of range, so the mix-up must be told before any fit.
UR_IN_DEGREES = {"format": "ur_rotvec", "units": {"length": "m", "angle": "deg"}}


def _ur_pin_and_touches(api: Api, n: int) -> tuple[str, str, JsonObject, list[Any]]:
    """A UR robot's tool with an active TCP, a reference point, and n touches of it written
    in degrees."""
    robot = api.robot("ur10", vendor="UR")
    tool = api.tool(robot["id"], "gripper")
    point, poses = _pin_and_touches(api, robot, tool, n, "ur_rotvec", {"angle": "deg"})
    return robot["id"], tool["id"], point, poses


def _is_ur_in_degrees(response: Any) -> JsonObject:
    assert response.status_code == 422, response.text
    problem: JsonObject = response.json()
    assert problem["type"].endswith("/convention-mismatch"), problem
    assert problem["suggestion"] == UR_IN_DEGREES, problem
    assert "nothing was stored" in problem["detail"]
    return problem


def test_check_with_a_ur_pendants_degrees_is_a_mix_up_not_out_of_range(api: Api) -> None:
    _, tool_id, point, poses = _ur_pin_and_touches(api, 3)
    body: JsonObject = {"reference_point_id": point["id"], "format": "ur_rotvec", "poses": poses}
    before = row_counts(TABLES)
    _is_ur_in_degrees(api.post(f"/v1/tools/{tool_id}/checks", body, scope="calibrate"))
    assert row_counts(TABLES) == before
    resent = api.post(f"/v1/tools/{tool_id}/checks", {**body, **UR_IN_DEGREES}, scope="calibrate")
    assert resent.status_code == 200, resent.text
    assert resent.json()["within_tolerance"] is True


def test_session_touch_with_a_ur_pendants_degrees_is_a_mix_up_from_the_first(api: Api) -> None:
    _, tool_id, _, poses = _ur_pin_and_touches(api, 1)
    session = api.post(
        f"/v1/tools/{tool_id}/sessions",
        {"method": "xyz_npoint", "format": "ur_rotvec"},
        scope="calibrate",
    ).json()
    path = f"/v1/sessions/{session['id']}/poses"
    _is_ur_in_degrees(api.post(path, {"pose": poses[0]}, scope="calibrate"))
    assert api.get(f"/v1/sessions/{session['id']}").json()["poses"] == []


def test_reference_touch_with_a_ur_pendants_degrees_is_a_mix_up(api: Api) -> None:
    robot_id, tool_id, _, poses = _ur_pin_and_touches(api, 1)
    touch: JsonObject = {"tool_id": tool_id, "format": "ur_rotvec", "pose": poses[0]}
    path = f"/v1/robots/{robot_id}/reference-points"
    before = row_counts(TABLES)
    problem = _is_ur_in_degrees(api.post(path, {"name": "p2", "touch": touch}, scope="calibrate"))
    assert problem["errors"][0]["loc"] == ["body", "touch", "format"]
    assert row_counts(TABLES) == before
    fixed = {"name": "p2", "touch": {**touch, **UR_IN_DEGREES}}
    created = api.post(path, fixed, scope="calibrate")
    assert created.status_code == 201, created.text
    assert np.allclose(created.json()["position_mm"], [650.0, 80.0, 210.0], atol=1e-6)
