"""Activation you can trust: rollback from the activation history, reasons, and `force` for a
version stored out of tolerance (API contract v1.2)."""

from __future__ import annotations

from typing import Any

import pytest
from sqlalchemy import select

from app.services.tools.activation import rollback_stack
from tests.api.touches import row_counts
from tests.conftest import Api
from tests.publish.plant_changes import out_of_tolerance_version

STATE = ("activations", "audit_events", "tcp_versions")


def _tool(api: Api) -> str:
    robot = api.robot("kr16", vendor="KUKA")
    return str(api.tool(robot["id"], "torch", slot=3)["id"])


def _issue_case(api: Api) -> str:
    """v2 accepted, v3 out_of_tolerance, v4 active (issue 24)."""
    tool_id = _tool(api)
    api.manual(tool_id, [0, 0, 150])
    api.manual(tool_id, [0, 0, 150.5])
    assert out_of_tolerance_version(api, tool_id) == 3
    assert api.manual(tool_id, [0, 0, 151])["active"] is True
    return tool_id


def _active(api: Api, tool_id: str) -> int | None:
    version: int | None = api.get(f"/v1/tools/{tool_id}").json()["active_version"]
    return version


def _audit(tool_id: str, action: str) -> list[dict[str, Any]]:
    from app.storage.db import get_engine
    from app.storage.models import AuditEvent

    with get_engine().connect() as conn:
        rows = conn.execute(
            select(AuditEvent.details)
            .where(AuditEvent.tool_id == tool_id, AuditEvent.action == action)
            .order_by(AuditEvent.id)
        ).scalars()
        return [dict(r or {}) for r in rows]


def test_rollback_returns_to_the_previously_active_version_not_the_number_below(
    api: Api,
) -> None:
    tool_id = _issue_case(api)
    etag = api.get(f"/v1/tools/{tool_id}").headers["etag"]
    response = api.post(
        f"/v1/tools/{tool_id}/rollback",
        {"reason": "v4 drifts on the weld seam"},
        scope="calibrate",
        headers={"If-Match": etag},
    )
    assert response.status_code == 200, response.text
    assert response.json()["active_version"] == 2
    assert response.headers["etag"] != etag
    assert api.get(f"/v1/tools/{tool_id}/tcp").json()["version"] == 2
    history = api.get(f"/v1/tools/{tool_id}/versions").json()["activations"]
    assert (history[-1]["version"], history[-1]["previous_version"]) == (2, 4)
    assert (history[-1]["reason"], history[-1]["reason_text"]) == (
        "rollback",
        "v4 drifts on the weld seam",
    )
    [event] = _audit(tool_id, "version.rollback")
    assert event["version"] == 2
    assert event["previous_version"] == 4
    assert (event["kind"], event["reason"]) == ("rollback", "v4 drifts on the weld seam")


def test_rollback_with_a_stale_etag_is_412_and_changes_nothing(api: Api) -> None:
    tool_id = _issue_case(api)
    etag = api.get(f"/v1/tools/{tool_id}").headers["etag"]
    api.manual(tool_id, [0, 0, 151.2])
    before = row_counts(STATE)
    stale = api.post(f"/v1/tools/{tool_id}/rollback", scope="calibrate", headers={"If-Match": etag})
    assert stale.status_code == 412
    assert row_counts(STATE) == before
    assert _active(api, tool_id) == 5


def test_rollback_never_picks_a_version_that_was_never_active(api: Api) -> None:
    tool_id = _tool(api)
    api.manual(tool_id, [0, 0, 150], activate="never")
    api.manual(tool_id, [0, 0, 151])
    assert _active(api, tool_id) == 2
    before = row_counts(STATE)
    refused = api.post(f"/v1/tools/{tool_id}/rollback", scope="calibrate")
    assert refused.status_code == 409
    problem = refused.json()
    assert problem["type"].endswith("/nothing-to-roll-back")
    assert "no version was active before version 2" in problem["detail"]
    assert row_counts(STATE) == before
    assert _active(api, tool_id) == 2


def test_rollback_of_a_tool_never_activated_is_409(api: Api) -> None:
    tool_id = _tool(api)
    refused = api.post(f"/v1/tools/{tool_id}/rollback", scope="calibrate")
    assert refused.status_code == 409
    assert "no version has been active yet" in refused.json()["detail"]


def test_repeated_rollbacks_walk_back_through_the_history(api: Api) -> None:
    tool_id = _tool(api)
    for z in (150, 150.5, 151, 151.5):
        api.manual(tool_id, [0, 0, z])
    walked = []
    for _ in range(3):
        response = api.post(f"/v1/tools/{tool_id}/rollback", scope="calibrate")
        assert response.status_code == 200, response.text
        walked.append(response.json()["active_version"])
    assert walked == [3, 2, 1]
    last = api.post(f"/v1/tools/{tool_id}/rollback", scope="calibrate")
    assert last.status_code == 409
    assert _active(api, tool_id) == 1


def test_rollback_after_switching_back_and_forth_does_not_ping_pong(api: Api) -> None:
    tool_id = _tool(api)
    api.manual(tool_id, [0, 0, 150])
    api.manual(tool_id, [0, 0, 150.5])
    for version in (1, 2):
        api.post(f"/v1/tools/{tool_id}/versions/{version}/activate", scope="calibrate")
    first = api.post(f"/v1/tools/{tool_id}/rollback", scope="calibrate")
    assert first.json()["active_version"] == 1
    # Version 2 was just rolled away from: a second rollback does not bring it back.
    second = api.post(f"/v1/tools/{tool_id}/rollback", scope="calibrate")
    assert second.status_code == 409
    assert _active(api, tool_id) == 1


@pytest.mark.parametrize(
    ("history", "stack"),
    [
        ([], []),
        ([(1, "calibration:auto"), (2, "calibration:auto")], [1, 2]),
        ([(1, "c"), (2, "c"), (4, "c"), (2, "rollback")], [1, 2]),
        ([(1, "c"), (2, "c"), (1, "explicit"), (2, "explicit")], [1, 2]),
        ([(1, "c"), (2, "c"), (3, "c"), (1, "explicit"), (3, "rollback")], [2, 3]),
        ([(1, "c"), (2, "c"), (3, "c"), (2, "rollback"), (1, "rollback")], [1]),
    ],
)
def test_rollback_stack_rule(history: list[tuple[int, str]], stack: list[int]) -> None:
    assert rollback_stack(history) == stack


def test_out_of_tolerance_version_needs_force_and_a_reason(api: Api) -> None:
    tool_id = _issue_case(api)
    path = f"/v1/tools/{tool_id}/versions/3/activate"
    before = row_counts(STATE)
    for body in (None, {}, {"reason": "looks fine to me"}):
        refused = api.post(path, body, scope="calibrate")
        assert refused.status_code == 409, refused.text
        problem = refused.json()
        assert problem["type"].endswith("/out-of-tolerance")
        assert "out_of_tolerance" in problem["detail"]
        assert '"force": true' in problem["detail"]
        assert problem["status"] == 409  # RFC 9457: the HTTP status, a number
        assert problem["version_status"] == "out_of_tolerance"
        assert problem["max_mm"] > 1.0  # the worst touch, as stored
    assert row_counts(STATE) == before
    assert _active(api, tool_id) == 4

    forced = api.post(
        path, {"force": True, "reason": "interim until the new torch arrives"}, scope="calibrate"
    )
    assert forced.status_code == 200, forced.text
    assert forced.json()["active_version"] == 3
    history = api.get(f"/v1/tools/{tool_id}/versions").json()["activations"]
    assert (history[-1]["reason"], history[-1]["reason_text"]) == (
        "forced",
        "interim until the new torch arrives",
    )
    event = _audit(tool_id, "version.activate")[-1]
    assert (event["version"], event["force"], event["status"]) == (3, True, "out_of_tolerance")
    assert (event["kind"], event["reason"]) == ("forced", "interim until the new torch arrives")


def test_explicit_activation_keeps_the_reason(api: Api) -> None:
    tool_id = _issue_case(api)
    response = api.post(
        f"/v1/tools/{tool_id}/versions/2/activate",
        {"reason": "  back to the commissioning TCP  "},
        scope="calibrate",
    )
    assert response.status_code == 200, response.text
    last = api.get(f"/v1/tools/{tool_id}/versions").json()["activations"][-1]
    assert (last["reason"], last["reason_text"]) == ("explicit", "back to the commissioning TCP")


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"reason": "x" * 501}, "reason"),
        ({"reason": ""}, "reason"),
        ({"reason": "   "}, "reason"),
        ({"reason": "a\x00b"}, "reason"),
        ({"force": True}, "reason"),
        ({"force": "yes", "reason": "r"}, "force"),
        ({"reason": "r", "forse": True}, "forse"),
    ],
)
def test_bad_activation_bodies_are_422_naming_the_field(
    api: Api, body: dict[str, Any], field: str
) -> None:
    tool_id = _issue_case(api)
    before = row_counts(STATE)
    for path in (f"/v1/tools/{tool_id}/versions/3/activate", f"/v1/tools/{tool_id}/rollback"):
        if path.endswith("rollback") and "force" in body:
            continue  # a rollback takes no force (refused as an unknown field)
        response = api.post(path, body, scope="calibrate")
        assert response.status_code == 422, (path, response.text)
        assert response.headers["content-type"].startswith("application/problem+json")
        locs = [e["loc"] for e in response.json()["errors"]]
        assert ["body", field] in locs, locs
    assert row_counts(STATE) == before
    assert _active(api, tool_id) == 4


def test_a_500_character_reason_is_kept_whole(api: Api) -> None:
    tool_id = _issue_case(api)
    reason = "r" * 500
    ok = api.post(f"/v1/tools/{tool_id}/rollback", {"reason": reason}, scope="calibrate")
    assert ok.status_code == 200, ok.text
    last = api.get(f"/v1/tools/{tool_id}/versions").json()["activations"][-1]
    assert last["reason_text"] == reason


def test_rollback_refuses_force(api: Api) -> None:
    tool_id = _issue_case(api)
    response = api.post(f"/v1/tools/{tool_id}/rollback", {"force": True}, scope="calibrate")
    assert response.status_code == 422
    assert response.json()["errors"][0]["loc"] == ["body", "force"]
    assert _active(api, tool_id) == 4


def test_activation_and_rollback_need_calibrate_scope(api: Api) -> None:
    tool_id = _issue_case(api)
    for path in (f"/v1/tools/{tool_id}/rollback", f"/v1/tools/{tool_id}/versions/2/activate"):
        assert api.post(path, scope="read").status_code == 403
    assert _active(api, tool_id) == 4


def test_keys_me_tells_each_key_its_own_scope_and_never_the_key(api: Api) -> None:
    for scope in ("read", "calibrate", "admin"):
        response = api.get("/v1/keys/me", scope=scope)
        assert response.status_code == 200, response.text
        body = response.json()
        assert (body["name"], body["scope"]) == (f"test-{scope}", scope)
        assert api.keys[scope] not in response.text
    anonymous = api.client.get("/v1/keys/me")
    assert anonymous.status_code == 401


def test_me_is_no_key_id_delete_and_options_of_it_answer_405_naming_get(api: Api) -> None:
    """Issue 51 #10: /v1/keys/me also matched DELETE /v1/keys/{key_id}, so OPTIONS answered
    Allow: DELETE, GET, HEAD and DELETE /v1/keys/me looked for a key with id 'me'. 'me' is a
    reserved word: the path is the caller's own key, read-only, and no key is ever id'd so."""
    for method in ("DELETE", "OPTIONS", "PUT"):
        response = api.request(method, "/v1/keys/me", "admin")
        assert response.status_code == 405, (method, response.status_code, response.text)
        assert response.headers["Allow"] == "GET, HEAD", method
        assert response.json()["type"].endswith("method-not-allowed")
    # and a real key id is still revoked at its own path
    made = api.post("/v1/keys", {"name": "to-revoke", "scope": "read"}).json()
    assert api.delete(f"/v1/keys/{made['id']}").status_code == 204


def test_a_key_cannot_be_named_me(api: Api) -> None:
    for name in ("me", "ME"):
        refused = api.post("/v1/keys", {"name": name, "scope": "read"})
        assert refused.status_code == 422, refused.text
        assert refused.json()["errors"][0]["loc"] == ["body", "name"]
        assert "reserved" in refused.json()["detail"]
