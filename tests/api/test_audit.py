"""GET /v1/audit: newest first, filtered, paginated with cursors bound to their query; what a
change records (a tolerance's old and new values, an activation's version); bad filters are
a 422 that names them; each filter is an index seek, not a scan."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from sqlalchemy import text

from tests.conftest import Api


@pytest.fixture
def history(api: Api) -> dict[str, Any]:
    """The history of `_history`: made once per backend, put back for each test (Api.world)."""
    return api.world(_history)


def _history(api: Api) -> dict[str, Any]:
    """Two robots with a tool each; a tolerance change, two versions and an activation."""
    r1 = api.robot("kr16", cell="cell-12")
    r2 = api.robot("irb", cell="cell-7")
    t1 = api.tool(r1["id"], "torch")
    t2 = api.tool(r2["id"], "gripper")
    patched = api.patch(
        f"/v1/tools/{t1['id']}",
        {"tolerance": {"max_rms_mm": 0.2}},
        headers={"X-Request-ID": "tighten-1"},
    )
    assert patched.status_code == 200, patched.text
    api.manual(t1["id"], [0, 0, 150], note="data sheet")
    api.manual(t1["id"], [0, 0, 151])
    activated = api.post(f"/v1/tools/{t1['id']}/versions/1/activate", scope="calibrate")
    assert activated.status_code == 200, activated.text
    return {"r1": r1, "r2": r2, "t1": t1, "t2": t2}


def _audit(api: Api, **params: Any) -> Any:
    response = api.get("/v1/audit", scope="admin", params=params)
    assert response.status_code == 200, response.text
    return response.json()


def test_newest_first_with_who_what_and_which_version(api: Api, history: dict[str, Any]) -> None:
    items = _audit(api, tool_id=history["t1"]["id"])["items"]
    # a manual TCP is active at once: its calibration event follows its activation
    assert [e["action"] for e in items] == [
        "version.activate",
        "calibration.create",
        "version.activate",
        "version.create",
        "calibration.create",
        "version.activate",
        "version.create",
        "tool.update",
        "tool.create",
    ]
    ids = [int(e["id"]) for e in items]
    assert ids == sorted(ids, reverse=True)
    assert set(items[0]) == {
        "id",
        "at",
        "action",
        "actor",
        "request_id",
        "resource_type",
        "resource_id",
        "robot_id",
        "tool_id",
        "version",
        "detail",
    }
    rollback = items[0]
    assert rollback["actor"] == "test-calibrate"
    assert rollback["version"] == 1
    assert rollback["detail"]["previous_version"] == 2
    assert rollback["robot_id"] == history["r1"]["id"]
    first = items[4]
    assert first["version"] == 1
    assert first["detail"]["note"] == "data sheet"
    assert first["detail"]["status"] == "accepted"


def test_a_tolerance_change_records_old_and_new_values_and_the_request(
    api: Api, history: dict[str, Any]
) -> None:
    (event,) = _audit(api, tool_id=history["t1"]["id"], action="tool.update")["items"]
    assert event["request_id"] == "tighten-1"
    assert event["actor"] == "test-admin"
    detail = event["detail"]
    assert detail["changed"] == ["tolerance"]
    assert detail["from"]["tolerance"]["max_rms_mm"] == 0.5
    assert detail["to"]["tolerance"]["max_rms_mm"] == 0.2
    assert (
        detail["to"]["tolerance"]["max_residual_mm"]
        == detail["from"]["tolerance"]["max_residual_mm"]
    )


def test_filters(api: Api, history: dict[str, Any]) -> None:
    r2 = history["r2"]["id"]
    by_robot = _audit(api, robot_id=r2)["items"]
    assert [e["action"] for e in by_robot] == ["tool.create", "robot.create"]
    assert {e["robot_id"] for e in by_robot} == {r2}
    by_actor = _audit(api, actor="test-calibrate")["items"]
    assert by_actor
    assert {e["actor"] for e in by_actor} == {"test-calibrate"}
    assert len(_audit(api, action="robot.create")["items"]) == 2
    assert _audit(api, action="robot.create", actor="nobody")["items"] == []
    now = datetime.now(UTC)
    everything = _audit(api)["items"]
    assert len(_audit(api, since=(now - timedelta(hours=1)).isoformat())["items"]) == len(
        everything
    )
    assert _audit(api, since=(now + timedelta(hours=1)).isoformat())["items"] == []
    assert _audit(api, until=(now - timedelta(hours=1)).isoformat())["items"] == []
    # since <= at < until: an event's own time is in [at, at + 1 us)
    at = everything[-1]["at"]
    later = (datetime.fromisoformat(at) + timedelta(microseconds=1)).isoformat()
    around = _audit(api, since=at, until=later)["items"]
    assert everything[-1]["id"] in [e["id"] for e in around]


def test_pages_follow_the_cursor_and_a_cursor_of_another_query_is_refused(
    api: Api, history: dict[str, Any]
) -> None:
    everything = _audit(api, limit=500)["items"]
    seen: list[str] = []
    page = _audit(api, limit=3)
    while True:
        seen += [e["id"] for e in page["items"]]
        if page["next_cursor"] is None:
            break
        page = _audit(api, limit=3, cursor=page["next_cursor"])
    assert seen == [e["id"] for e in everything]

    tool_page = _audit(api, tool_id=history["t1"]["id"], limit=2)
    cursor = tool_page["next_cursor"]
    assert cursor is not None
    for other in (
        {},
        {"tool_id": history["t2"]["id"]},
        {"tool_id": history["t1"]["id"], "action": "tool.create"},
    ):
        response = api.get("/v1/audit", scope="admin", params={**other, "cursor": cursor})
        assert response.status_code == 422, response.text
        problem = response.json()
        assert problem["type"].endswith("/invalid-cursor")
        assert "another query" in problem["detail"]
        assert problem["errors"][0]["loc"] == ["query", "cursor"]
    same = api.get(
        "/v1/audit", scope="admin", params={"tool_id": history["t1"]["id"], "cursor": cursor}
    )
    assert same.status_code == 200


@pytest.mark.parametrize(
    ("params", "field", "words"),
    [
        ({"tool": "x"}, "tool", "unknown query parameter tool"),
        ({"tool_id": "a", "robotid": "b", "acter": "c"}, "acter", "acter, robotid"),
        (
            {"since": "2026-11-24T06:00:00Z", "until": "2026-11-24T05:00:00Z"},
            "since",
            "after until",
        ),
        ({"since": "2026-11-24T06:00:00"}, "since", "timezone"),
        ({"action": ""}, "action", "at least 1"),
        ({"tool_id": "../../etc"}, "tool_id", "pattern"),
        ({"cursor": "zz"}, "cursor", "pattern"),
    ],
)
def test_bad_filters_are_a_422_naming_them(
    api: Api, history: dict[str, Any], params: dict[str, str], field: str, words: str
) -> None:
    response = api.get("/v1/audit", scope="admin", params=params)
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    problem = response.json()
    assert ["query", field] in [e["loc"] for e in problem["errors"]], problem
    assert words.lower() in (problem["detail"] + str(problem["errors"])).lower(), problem


def test_an_interval_that_ends_before_it_starts_is_its_own_problem(api: Api) -> None:
    """Schema-valid, so not /validation (the contract test's hook): /invalid-interval."""
    params = {"since": "2026-11-24T06:00:00Z", "until": "2026-11-24T05:00:00+00:00"}
    problem = api.get("/v1/audit", scope="admin", params=params).json()
    assert problem["type"].endswith("/invalid-interval")
    assert problem["status"] == 422


def test_the_trail_needs_an_admin_key(api: Api, history: dict[str, Any]) -> None:
    assert api.get("/v1/audit", scope="calibrate").status_code == 403
    assert api.get("/v1/audit", scope="read").status_code == 403


@pytest.mark.parametrize(
    "where",
    [
        "tool_id = 'x'",
        "robot_id = 'x'",
        "action = 'x'",
        "actor = 'x'",
        "at >= '2026-01-01'",
        "at >= '2026-01-01' AND at < '2026-02-01'",
        "tool_id = 'x' AND action = 'x'",
        "1 = 1",
    ],
)
def test_each_filter_is_an_index_seek_not_a_scan(api: Api, where: str) -> None:
    """SQLite's plan for a page under each filter (newest first, after a cursor): no full scan
    of audit_events and no sort of its rows."""
    from app.db import get_engine

    engine = get_engine()
    if engine.dialect.name != "sqlite":
        pytest.skip("the plan is read from SQLite's EXPLAIN QUERY PLAN")
    sql = f"SELECT * FROM audit_events WHERE {where} AND id < 1000 ORDER BY id DESC LIMIT 51"
    with engine.connect() as conn:
        plan = " | ".join(str(r[-1]) for r in conn.execute(text(f"EXPLAIN QUERY PLAN {sql}")))
    assert "SCAN audit_events" not in plan.replace("SCAN audit_events USING", "SEEK"), plan
    if where.startswith("at"):
        return  # a time range is a seek in (at, id), then its rows sorted by id
    assert "TEMP B-TREE" not in plan, plan
