"""The spec says what the server does: found by schemathesis `--checks all`, fixed, kept."""

from __future__ import annotations

import pytest

from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses
from tests.conftest import Api


@pytest.mark.parametrize(
    ("path", "allowed"),
    [
        ("/v1/robots", "GET, HEAD, POST"),
        ("/v1/robots/x1", "DELETE, GET, HEAD, PATCH"),
        ("/v1/keys", "GET, HEAD, POST"),
    ],
)
def test_405_lists_every_method_of_the_path(api: Api, path: str, allowed: str) -> None:
    response = api.request("PUT", path, "admin")
    assert response.status_code == 405
    assert response.headers["Allow"] == allowed
    assert allowed in response.json()["detail"]


def test_a_boolean_or_a_string_is_not_a_number(api: Api) -> None:
    robot = api.robot()
    for bad in (False, "0.5"):
        link = {"a": 0.0, "alpha": 0.0, "d": 0.0, "theta_offset": bad}
        response = api.patch(
            f"/v1/robots/{robot['id']}", {"kinematics": {"convention": "dh", "links": [link]}}
        )
        assert response.status_code == 422, response.text
    assert (
        api.post(f"/v1/robots/{robot['id']}/tools", {"name": "t", "slot": True}).status_code == 422
    )
    assert (
        api.post(f"/v1/robots/{robot['id']}/tools", {"name": "t", "slot": 3.0}).status_code == 201
    )


def test_a_vanishing_touch_noise_is_refused_not_a_500(api: Api) -> None:
    """Regression: touch_noise_mm = 5e-324 squared to 0 and made the weights singular."""
    robot = api.robot()
    tool = api.tool(robot["id"], tolerance={"touch_noise_mm": 1e-3})
    body = {
        "method": "xyz_npoint",
        "format": "xyz_wxyz",
        "poses": as_poses(simulate_touches(6, seed=1)),
        "options": {"touch_noise_mm": 5e-324},
    }
    response = api.post(f"/v1/tools/{tool['id']}/calibrations", body, scope="calibrate")
    assert response.status_code == 422, response.text
    assert response.json()["errors"][0]["loc"] == ["body", "options", "touch_noise_mm"]


def test_names_with_c1_controls_are_refused_by_the_schema(api: Api) -> None:
    response = api.post("/v1/robots", {"name": "\u0085"})
    assert response.status_code == 422
    assert api.post("/v1/robots", {"name": "cell\u00a012"}).status_code == 201


def test_if_match_of_the_wrong_shape_is_422_and_a_stale_one_412(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    path = f"/v1/tools/{tool['id']}"
    shape = api.patch(path, {"slot": 2}, headers={"If-Match": "null"})
    assert shape.status_code == 422
    assert shape.json()["errors"][0]["loc"] == ["header", "if-match"]
    stale = api.patch(path, {"slot": 2}, headers={"If-Match": '"' + "0" * 20 + '"'})
    assert stale.status_code == 412


def test_if_match_with_a_weak_or_foreign_tag_fails_the_precondition(api: Api) -> None:
    """RFC 9110 13.1.1: If-Match compares strongly. The tool's own tag weakened (as a
    compressing proxy hands it on) or another server's tag is a well-formed header that does
    not match: 412, not 422; the current tag still passes."""
    robot = api.robot()
    tool = api.tool(robot["id"])
    path = f"/v1/tools/{tool['id']}"
    etag = api.get(path).headers["etag"]
    for header in (f"W/{etag}", '"v1"', f'"v1", W/{etag}'):
        refused = api.patch(path, {"slot": 2}, headers={"If-Match": header})
        assert refused.status_code == 412, (header, refused.text)
        assert refused.json()["type"].endswith("/precondition-failed")
    assert api.patch(path, {"slot": 2}, headers={"If-Match": f'"v1", {etag}'}).status_code == 200


@pytest.mark.parametrize("path", ["/health", "/ui/", "/ui/tools/x1", "/ready"])
def test_head_is_answered_wherever_get_is(api: Api, path: str) -> None:
    """HEAD /health and /ui/ answered 405: monitors and load balancers probe with HEAD."""
    get = api.client.get(path)
    head = api.client.head(path)
    assert head.status_code == get.status_code == 200
    assert head.content == b""
    assert head.headers["content-type"] == get.headers["content-type"]
    assert head.headers["content-length"] == str(len(get.content))


def test_head_of_a_keyed_resource_needs_the_key_as_get_does(api: Api) -> None:
    robot = api.robot()
    assert api.client.head(f"/v1/robots/{robot['id']}").status_code == 401
    head = api.request("HEAD", f"/v1/robots/{robot['id']}", "read")
    assert head.status_code == 200
    assert head.content == b""
    assert api.request("HEAD", "/v1/robots/nope", "read").status_code == 404
