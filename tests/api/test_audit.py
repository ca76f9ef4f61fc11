"""GET /v1/audit: newest first, filtered, paginated with cursors bound to their query; what a
change records (a tolerance's old and new values, an activation's version); bad filters are
a 422 that names them; each filter is an index seek, not a scan."""

from __future__ import annotations

import re
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from sqlalchemy import Engine, text

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
        "frame_id",
        "version",
        "detail",
    }
    assert items[0]["frame_id"] is None  # a tool's event names no frame
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


#: Events in the trail whose plans are read, and the distinct values of each filtered column
#: among them (a filter keeps about 1/n of the trail): enough that PostgreSQL's planner, from
#: the table's statistics, reads a filtered page through the filter's index. With a few
#: hundred rows it rightly reads the table, index or not; with a value in one event of 40 it
#: walks the primary key back and filters, expecting a page within 2 000 rows.
TRAIL_ROWS = 20_000
_DISTINCT = {"tool_id": 200, "robot_id": 100, "action": 200, "actor": 200}
_YEAR = datetime(2026, 1, 1, tzinfo=UTC)
_STEP = timedelta(minutes=26)  # TRAIL_ROWS events spread over the year, `at` growing with id


def _value(column: str, i: int) -> str:
    return f"{column.removesuffix('_id')}-{i % _DISTINCT[column]:04d}"


@pytest.fixture
def long_trail(api: Api) -> Iterator[None]:
    """TRAIL_ROWS audit events, inserted at the database (through the API it would take
    minutes); on PostgreSQL the table then analyzed, as autovacuum does after a bulk load.
    SQLite is planned as a deployment has it: the migrations never run ANALYZE there."""
    from sqlalchemy import insert

    from app.services.audit.writes import row
    from app.storage.db import get_engine
    from app.storage.models import AuditEvent

    rows = [
        row(
            at=_YEAR + i * _STEP,
            actor=_value("actor", i // 3),
            api_key_id=None,
            # out of step with the tools: pairs repeat. 200 words no version writes, for the
            # planner's statistics: the trail serves what a row holds (StoredWord)
            action=_value("action", i // 7),  # type: ignore[arg-type]
            resource_type="tool",
            resource_id=_value("tool_id", i),
            robot_id=_value("robot_id", i),
            tool_id=_value("tool_id", i),
            details=None,
        )
        for i in range(TRAIL_ROWS)
    ]
    engine = get_engine()
    with engine.begin() as conn:
        conn.execute(insert(AuditEvent), rows)
    _analyze(engine)
    yield
    with engine.begin() as conn:
        conn.execute(text("DELETE FROM audit_events"))
    _analyze(engine)  # the tests after plan against an empty trail again


def _analyze(engine: Engine) -> None:
    if engine.dialect.name == "postgresql":
        with engine.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
            conn.execute(text("ANALYZE audit_events"))


#: SQLite's walks of the primary key, newest first: from the newest event, from a cursor.
_SQLITE_ROWID = ("SCAN audit_events", "SEARCH audit_events USING INTEGER PRIMARY KEY (rowid<?)")

#: GET /v1/audit's filters, each with the columns of the index its pages must be read through
#: (the filtered columns, then the id: an equality's rows come out newest first; a time
#: range's are a seek to its start, then sorted; None: no filter, the primary key), and the
#: walks of the primary key SQLite may take instead. Without statistics it walks the ids
#: back and filters on `at` from the newest event for `since` alone, and from the cursor in
#: any range: as `at` grows with the id, the page's events come first. (Known: the page that
#: reaches the start of the range goes on reading every older event.)
_FILTERS: list[tuple[dict[str, str], tuple[str, ...] | None, tuple[str, ...]]] = [
    ({"tool_id": _value("tool_id", 17)}, ("tool_id", "id"), ()),
    ({"robot_id": _value("robot_id", 17)}, ("robot_id", "id"), ()),
    ({"action": _value("action", 17)}, ("action", "id"), ()),
    ({"actor": _value("actor", 17)}, ("actor", "id"), ()),
    ({"since": (_YEAR + 19_900 * _STEP).isoformat()}, ("at", "id"), _SQLITE_ROWID),
    (
        {
            "since": (_YEAR + 8_000 * _STEP).isoformat(),
            "until": (_YEAR + 8_100 * _STEP).isoformat(),
        },
        ("at", "id"),
        _SQLITE_ROWID[1:],
    ),
    (
        {"tool_id": _value("tool_id", 17), "action": _value("action", 17 // 7)},
        ("tool_id", "action", "id"),
        (),
    ),
    ({}, None, _SQLITE_ROWID),
]


def _index_on(columns: tuple[str, ...]) -> str:
    """The name of the model's index of audit_events on exactly these columns, in order."""
    from app.storage.models import AuditEvent, table_of

    (name,) = [
        str(ix.name)
        for ix in table_of(AuditEvent).indexes
        if tuple(c.name for c in ix.columns) == columns
    ]
    return name


def _page_statements(api: Api, params: dict[str, str]) -> list[tuple[str, Any]]:
    """The statements (with their parameters) GET /v1/audit sends to read audit_events for a
    page of the default size under `params`: the first, and one after a cursor."""
    from sqlalchemy import event

    from app.storage.db import get_engine

    cursor = _audit(api, limit=1, **params)["next_cursor"]
    assert cursor, params
    sent: list[tuple[str, Any]] = []

    def grab(conn: object, cur: object, statement: str, parameters: Any, *_: object) -> None:
        if "FROM audit_events" in statement:
            sent.append((statement, parameters))

    event.listen(get_engine(), "before_cursor_execute", grab)
    try:
        assert _audit(api, **params)["items"], params
        assert _audit(api, cursor=cursor, **params)["items"], params
    finally:
        event.remove(get_engine(), "before_cursor_execute", grab)
    assert len(sent) == 2, sent
    return sent


def _plan(engine: Engine, statement: str, parameters: Any) -> list[str]:
    """The database's plan for a statement as the app sent it, with its values: SQLite's
    EXPLAIN QUERY PLAN, PostgreSQL's EXPLAIN."""
    sqlite = engine.dialect.name == "sqlite"
    with engine.connect() as conn:
        prefix = "EXPLAIN QUERY PLAN " if sqlite else "EXPLAIN "
        rows = conn.exec_driver_sql(prefix + statement, parameters).all()
    return [str(r[-1] if sqlite else r[0]).strip() for r in rows]


def _sqlite_wrong(
    plan: list[str], columns: tuple[str, ...] | None, walks: tuple[str, ...]
) -> str | None:
    """What is wrong with SQLite's plan for a page filtered on `columns` (None: nothing)."""
    if len(plan) == 1 and plan[0] in walks:
        return None
    if columns is None:
        return "not a walk of the ids from the newest or the cursor"
    seek = re.fullmatch(r"SEARCH audit_events USING (COVERING )?INDEX (\w+) \((.*)\)", plan[0])
    if seek is None or seek.group(2) != _index_on(columns):
        return f"not a seek in {_index_on(columns)}"
    if not seek.group(3).startswith(columns[0]):
        return "the seek does not start at the filter's column"
    sorted_ = plan[1:] == ["USE TEMP B-TREE FOR ORDER BY"]
    if len(plan) > 1 and not (sorted_ and columns[0] == "at"):
        return "an equality's rows sorted (the index should give them newest first)"
    return None


_PG_READS = re.compile(
    r"(Seq Scan|Index Scan|Index Only Scan|Bitmap Heap Scan|Bitmap Index Scan)"
    r"(?: Backward)? (?:using|on) (\w+)"
)


def _postgresql_wrong(
    plan: list[str], columns: tuple[str, ...] | None, walks: tuple[str, ...]
) -> str | None:
    """What is wrong with PostgreSQL's plan for a page filtered on `columns` (None: nothing).
    A bitmap scan and a sort are fine when the filter's rows fit in a page."""
    want = "pk_audit_events" if columns is None else _index_on(columns)
    reads = _PG_READS.findall("\n".join(plan))
    index_reads = [name for kind, name in reads if kind != "Bitmap Heap Scan"]
    if not reads or any(kind == "Seq Scan" for kind, _ in reads) or set(index_reads) != {want}:
        return f"not read through {want} alone"
    return None


def test_each_filter_is_a_seek_in_its_index(api: Api, long_trail: None) -> None:
    """The plans of the very statements GET /v1/audit sends for a page under each filter (the
    first, and one after a cursor), on a trail of TRAIL_ROWS events: each page reads
    audit_events through its filter's index alone (no scan of the table, of its primary key
    or of another index), and on SQLite an equality's events come out of the index newest
    first, unsorted. Fails if any of the indexes is missing from the database."""
    from app.storage.db import get_engine

    engine = get_engine()
    judge = _sqlite_wrong if engine.dialect.name == "sqlite" else _postgresql_wrong
    wrong = []
    for params, columns, walks in _FILTERS:
        for statement, parameters in _page_statements(api, params):
            plan = _plan(engine, statement, parameters)
            reason = judge(plan, columns, walks)
            if reason is not None:
                where = " ".join(statement.split()).partition(" FROM ")[2]
                wrong.append(f"{params}: {reason}\n  FROM {where}\n  " + "\n  ".join(plan))
    assert not wrong, "\n".join(wrong)
