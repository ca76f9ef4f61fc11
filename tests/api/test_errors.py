"""Every kind of bad input gets a problem+json naming the field and the reason, never a 500."""

from __future__ import annotations

import json
from collections.abc import Iterator

import httpx
import pytest

from app.api.problem_json import problem_response
from app.jsontypes import JsonObject
from tests.conftest import Api

PROBLEM = "application/problem+json"


def _problem(response: httpx.Response, status: int, type_suffix: str) -> JsonObject:
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith(PROBLEM)
    body = response.json()
    assert body["status"] == status
    assert body["type"].endswith("/" + type_suffix), body
    assert body["title"]
    assert body["detail"]
    return dict(body)


def test_unknown_robot_id_is_404_naming_the_id(api: Api) -> None:
    body = _problem(api.get("/v1/robots/nope"), 404, "not-found")
    assert "nope" in body["detail"]


def test_unknown_tool_and_calibration_ids_are_404(api: Api) -> None:
    _problem(api.get("/v1/tools/missing-tool/tcp"), 404, "not-found")
    _problem(api.get("/v1/calibrations/missing-cal"), 404, "not-found")
    _problem(api.post("/v1/robots/missing/tools", {"name": "t"}), 404, "not-found")


def test_duplicate_robot_name_is_409_naming_name(api: Api) -> None:
    api.robot("same")
    body = _problem(api.post("/v1/robots", {"name": "same"}), 409, "conflict")
    assert body["errors"] == [{"loc": ["body", "name"], "msg": "already taken"}]


def test_duplicate_tool_name_and_slot_are_409(api: Api) -> None:
    robot = api.robot()
    api.tool(robot["id"], "gripper", slot=3)
    by_name = _problem(
        api.post(f"/v1/robots/{robot['id']}/tools", {"name": "gripper"}), 409, "conflict"
    )
    assert by_name["errors"][0]["loc"] == ["body", "name"]
    by_slot = _problem(
        api.post(f"/v1/robots/{robot['id']}/tools", {"name": "torch", "slot": 3}), 409, "conflict"
    )
    assert by_slot["errors"][0]["loc"] == ["body", "slot"]
    assert "slot 3" in by_slot["detail"]


def test_wrong_type_is_422_naming_field(api: Api) -> None:
    robot = api.robot()
    body = _problem(
        api.post(f"/v1/robots/{robot['id']}/tools", {"name": "t", "slot": "three"}),
        422,
        "validation",
    )
    assert body["errors"][0]["loc"] == ["body", "slot"]


def test_missing_field_is_422_naming_field(api: Api) -> None:
    body = _problem(api.post("/v1/robots", {"vendor": "KUKA"}), 422, "validation")
    assert body["errors"][0]["loc"] == ["body", "name"]
    assert "required" in body["errors"][0]["msg"].lower()


def test_unknown_field_is_422_naming_it(api: Api) -> None:
    body = _problem(api.post("/v1/robots", {"name": "r", "vendr": "KUKA"}), 422, "validation")
    assert body["errors"][0]["loc"] == ["body", "vendr"]


def test_a_robot_model_given_as_a_bare_name_is_told_the_object_to_send(api: Api) -> None:
    """`"kinematics": "tm5_900"` answered three "Input should be a valid dictionary or
    instance of ...Kinematics" lines at one loc (issue 51, defect 9): one error names the
    object to send, on creation, on change and in /v1/solve's inline model."""
    created = _problem(
        api.post("/v1/robots", {"name": "tm", "kinematics": "tm5_900"}), 422, "validation"
    )
    assert created["errors"] == [
        {
            "loc": ["body", "kinematics"],
            "msg": 'a robot model is an object, not a string: send {"preset": "tm5_900"}',
        }
    ]
    assert created["detail"] == f"body.kinematics: {created['errors'][0]['msg']}"
    robot = api.robot("tm")
    unknown = api.request(
        "PATCH", f"/v1/robots/{robot['id']}", "admin", json={"kinematics": "tm12"}
    ).json()
    [error] = unknown["errors"]
    assert error["loc"] == ["body", "kinematics"]
    assert '{"preset": NAME} with NAME one of tm5_900, ur10e' in error["msg"]
    assert '{"convention": ..., "links": [...]} or {"urdf": "<robot ...>"}' in error["msg"]
    solve = api.post(
        "/v1/solve",
        {"method": "xyz_npoint", "format": "joints", "poses": [[0] * 6] * 4, "kinematics": 5},
        scope="calibrate",
    ).json()
    [error] = solve["errors"]
    assert error["loc"] == ["body", "kinematics"]
    assert error["msg"].startswith('a robot model is an object, not int: send {"preset"')


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_numbers_are_422_non_finite(api: Api, token: str) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    raw = '{"method": "manual", "tcp": {"position_mm": [0, 0, TOKEN]}}'.replace("TOKEN", token)
    response = api.client.post(
        f"/v1/tools/{tool['id']}/calibrations",
        content=raw,
        headers={**api.headers("calibrate"), "content-type": "application/json"},
    )
    body = _problem(response, 422, "non-finite")
    assert body["errors"][0]["loc"] == ["body", "tcp", "position_mm", 2]
    assert api.get(f"/v1/tools/{tool['id']}/versions").json()["items"] == []


def test_a_form_body_is_told_to_send_json(api: Api) -> None:
    """curl -d without -H 'Content-Type: application/json' sends a form: the 422 says which
    header to send; a JSON body of the wrong shape does not get that hint."""
    form = api.client.post(
        "/v1/robots",
        content="name=r1",
        headers={**api.headers(), "content-type": "application/x-www-form-urlencoded"},
    )
    problem = _problem(form, 422, "validation")
    assert "application/x-www-form-urlencoded" in problem["detail"]
    assert "Content-Type: application/json" in problem["detail"]
    shaped = api.post("/v1/robots", ["r1"])
    assert "Content-Type" not in _problem(shaped, 422, "validation")["detail"]


def test_unknown_format_is_422_naming_format(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    response = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        {"method": "manual", "format": "kuka_xyz", "poses": [[0, 0, 0, 0, 0, 0]]},
        scope="calibrate",
    )
    body = _problem(response, 422, "validation")
    assert body["errors"][0]["loc"] == ["body", "format"]
    assert "kuka_abc" in body["errors"][0]["msg"]


def test_unknown_method_is_422_naming_method(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    body = _problem(
        api.post(f"/v1/tools/{tool['id']}/calibrations", {"method": "guess"}, scope="calibrate"),
        422,
        "validation",
    )
    assert body["errors"][0]["loc"] == ["body", "method"]


def test_body_over_one_mib_is_413(api: Api) -> None:
    padding = "x" * (1024 * 1024)
    response = api.post("/v1/robots", {"name": "big", "description": padding})
    _problem(response, 413, "payload-too-large")
    assert api.get("/v1/robots").json()["items"] == []


def test_chunked_body_over_limit_is_413(api: Api) -> None:
    def chunks() -> Iterator[bytes]:
        yield b'{"name": "'
        for _ in range(20):
            yield b"y" * 65536
        yield b'"}'

    response = api.client.post(
        "/v1/robots",
        content=chunks(),
        headers={**api.headers("admin"), "content-type": "application/json"},
    )
    _problem(response, 413, "payload-too-large")


def test_scope_too_small_is_403_and_no_key_is_401(api: Api) -> None:
    body = _problem(api.post("/v1/robots", {"name": "r"}, scope="calibrate"), 403, "forbidden")
    assert "admin" in body["detail"]
    assert "calibrate" in body["detail"]
    _problem(api.client.get("/v1/robots"), 401, "unauthorized")
    _problem(
        api.client.get("/v1/robots", headers={"Authorization": "Bearer wrong"}), 401, "unauthorized"
    )
    _problem(
        api.client.get("/v1/robots", headers={"Authorization": "Basic abc"}), 401, "unauthorized"
    )


def test_read_key_cannot_calibrate(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    _problem(
        api.post(
            f"/v1/tools/{tool['id']}/calibrations",
            {"method": "manual", "tcp": {"position_mm": [0, 0, 1]}},
            scope="read",
        ),
        403,
        "forbidden",
    )


def test_unknown_route_and_wrong_method_are_problems(api: Api) -> None:
    _problem(api.get("/v1/nothing-here"), 404, "not-found")
    _problem(api.client.put("/v1/robots", headers=api.headers()), 405, "method-not-allowed")


def test_malformed_json_is_422(api: Api) -> None:
    response = api.client.post(
        "/v1/robots",
        content=b'{"name": ',
        headers={**api.headers(), "content-type": "application/json"},
    )
    _problem(response, 422, "validation")


def test_limit_over_max_is_422_and_bad_cursor_is_422(api: Api) -> None:
    body = _problem(api.get("/v1/robots?limit=501"), 422, "validation")
    assert body["errors"][0]["loc"] == ["query", "limit"]
    body = _problem(api.get("/v1/robots?cursor=garbage"), 422, "validation")
    assert body["errors"][0]["loc"] == ["query", "cursor"]


def test_bad_quaternion_length_is_422(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    response = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        {"method": "manual", "tcp": {"position_mm": [0, 0, 1], "quaternion": [1, 0, 0]}},
        scope="calibrate",
    )
    body = _problem(response, 422, "validation")
    assert body["errors"][0]["loc"] == ["body", "tcp", "quaternion"]


def test_non_unit_quaternion_is_422_invalid_rotation(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    response = api.post(
        f"/v1/tools/{tool['id']}/calibrations",
        {"method": "manual", "tcp": {"position_mm": [0, 0, 1], "quaternion": [2, 0, 0, 0]}},
        scope="calibrate",
    )
    body = _problem(response, 422, "invalid-rotation")
    assert body["errors"][0]["loc"][:3] == ["body", "tcp", "quaternion"]
    assert json.dumps(body).count("NaN") == 0


def test_nul_byte_in_a_path_id_is_422_not_a_database_error(api: Api) -> None:
    # PostgreSQL refuses NUL in text; it must be turned away before any query.
    body = _problem(api.get("/v1/tools/%00/versions/1"), 422, "validation")
    assert body["errors"][0]["loc"] == ["path", "tool_id"]
    body = _problem(
        api.post("/v1/robots/%00/laser-devices", {"name": "x"}, scope="calibrate"),
        422,
        "validation",
    )
    assert ["path", "robot_id"] in [e["loc"] for e in body["errors"]]


def test_control_characters_in_names_and_body_ids_are_422(api: Api) -> None:
    body = _problem(api.post("/v1/robots", {"name": "kr\u000016"}), 422, "validation")
    assert body["errors"][0]["loc"] == ["body", "name"]
    body = _problem(api.post("/v1/robots", {"name": "kr16", "cell": "c\n1"}), 422, "validation")
    assert body["errors"][0]["loc"] == ["body", "cell"]
    robot = api.robot()
    tool = api.tool(robot["id"])
    api.manual(tool["id"], [0, 0, 100])
    body = _problem(
        api.post(
            f"/v1/tools/{tool['id']}/checks",
            {
                "reference_point_id": "\u0000",
                "format": "xyz_wxyz",
                "poses": [[0, 0, 0, 1, 0, 0, 0]],
            },
            scope="calibrate",
        ),
        422,
        "validation",
    )
    assert body["errors"][0]["loc"] == ["body", "reference_point_id"]


def test_body_that_is_not_utf8_is_422(api: Api) -> None:
    response = api.client.post(
        "/v1/robots",
        content=b'{"name": "\xff\xfe"}',
        headers={**api.headers(), "content-type": "application/json"},
    )
    body = _problem(response, 422, "validation")
    assert body["errors"][0]["loc"] == ["body"]


def test_extension_members_never_replace_the_problems_own() -> None:
    """RFC 9457: `status` is the HTTP status (a number), `type`, `title` and `detail` say what
    happened; an error's extension members stand beside them."""
    response = problem_response(
        status=409,
        kind="out-of-tolerance",
        title="Out of tolerance",
        detail="why and how",
        extra={"status": "out_of_tolerance", "title": "x", "version_status": "out_of_tolerance"},
    )
    body = json.loads(bytes(response.body))
    assert (body["status"], body["title"], body["detail"]) == (
        409,
        "Out of tolerance",
        "why and how",
    )
    assert body["version_status"] == "out_of_tolerance"


@pytest.mark.parametrize(
    ("path", "name"),
    [
        ("/v1/robots", "cell"),
        ("/v1/robots", "name"),
        ("/v1/tools", "cell"),
        ("/v1/tools", "q"),
        ("/v1/audit", "action"),
        ("/v1/audit", "actor"),
    ],
)
def test_a_control_character_in_a_text_filter_is_422_naming_it(
    api: Api, path: str, name: str
) -> None:
    # PostgreSQL refuses NUL in a text parameter: the filter reached it and answered 500
    # (found by the contract test's fuzzing of GET /v1/audit?actor=...%00).
    for value in ("weld\x00", "cell\n12"):
        refused = api.get(path, scope="admin", params={name: value})
        assert refused.status_code == 422, refused.text
        assert refused.json()["errors"][0]["loc"] == ["query", name], refused.text
    assert api.get(path, scope="admin", params={name: "cell 12 / weld-3"}).status_code == 200
