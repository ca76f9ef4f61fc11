"""Concurrent writes that collide get the 409 a sequential one gets, on both backends.

SQLite serialises writers (BEGIN IMMEDIATE); on PostgreSQL two requests can both pass the
"is the name free?" check, and the loser meets the unique constraint at insert."""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from tests.conftest import Api

N = 8


def _at_once(fn: Callable[[int], Any]) -> list[Any]:
    barrier = threading.Barrier(N)

    def run(i: int) -> Any:
        barrier.wait()
        return fn(i)

    with ThreadPoolExecutor(N) as pool:
        return list(pool.map(run, range(N)))


def test_same_robot_name_at_once(api: Api) -> None:
    responses = _at_once(lambda i: api.post("/v1/robots", {"name": "twin"}))
    codes = sorted(r.status_code for r in responses)
    assert codes == [201] + [409] * (N - 1)
    for r in responses:
        if r.status_code == 409:
            assert r.json()["errors"][0]["loc"] == ["body", "name"]


def test_same_reference_point_name_at_once(api: Api) -> None:
    robot = api.robot()
    responses = _at_once(
        lambda i: api.post(
            f"/v1/robots/{robot['id']}/reference-points",
            {"name": "pin", "position_mm": [i, 0, 0]},
            scope="calibrate",
        )
    )
    assert sorted(r.status_code for r in responses) == [201] + [409] * (N - 1)


def test_same_idempotency_key_on_different_tools_at_once(api: Api) -> None:
    robot = api.robot()
    tools = [api.tool(robot["id"], f"t{i}") for i in range(N)]
    body = {"method": "manual", "tcp": {"position_mm": [0, 0, 100]}}
    responses = _at_once(
        lambda i: api.post(
            f"/v1/tools/{tools[i]['id']}/calibrations",
            body,
            scope="calibrate",
            headers={"Idempotency-Key": "shared"},
        )
    )
    codes = sorted(r.status_code for r in responses)
    assert codes == [201] + [409] * (N - 1), [r.text for r in responses]
    for r in responses:
        if r.status_code == 409:
            assert r.json()["type"].endswith("/idempotency-key-reused")
    versions = [len(api.get(f"/v1/tools/{t['id']}/versions").json()["items"]) for t in tools]
    assert sorted(versions) == [0] * (N - 1) + [1]


def test_same_idempotency_key_and_body_at_once_gives_one_version(api: Api) -> None:
    robot = api.robot()
    tool = api.tool(robot["id"])
    body = {"method": "manual", "tcp": {"position_mm": [0, 0, 100]}}
    responses = _at_once(
        lambda i: api.post(
            f"/v1/tools/{tool['id']}/calibrations",
            body,
            scope="calibrate",
            headers={"Idempotency-Key": "retry"},
        )
    )
    assert [r.status_code for r in responses] == [201] * N
    assert {r.json()["id"] for r in responses} == {responses[0].json()["id"]}
    assert len(api.get(f"/v1/tools/{tool['id']}/versions").json()["items"]) == 1
