"""What app.services.tools.versions serves and keeps up to date: the active TCP the publisher
sends (served_tcp), the tool table's order, a cell key's writes limited to its cells, and the
stored drift trend refreshed by every new version and activation (issue 51: each of these could
be broken with no test failing)."""

from __future__ import annotations

from app.methods.requests import CALIBRATION_REQUESTS
from app.security.auth import Principal
from app.services.calibrations import writes
from app.services.tools import versions
from app.services.tools.drift import refresh_drift
from app.services.tools.tools import get_tool
from app.storage.db import session_scope
from tests.conftest import Api

ACTOR = Principal(key_id="test", name="test", scope="admin")


def test_served_tcp_is_the_active_version_of_that_tool(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    tool = api.tool(robot["id"], "torch", slot=3)
    api.tool(robot["id"], "gripper", slot=4)
    api.manual(tool["id"], [0, 0, 150])
    api.manual(tool["id"], [1, 2, 151])
    with session_scope(write=False) as session:
        document, etag = versions.served_tcp(
            session, tool_id=tool["id"], fmt=None, if_none_match=None
        )
        assert document is not None
        assert (document.tool_id, document.robot_id) == (tool["id"], robot["id"])
        assert (document.tool_name, document.slot, document.version) == ("torch", 3, 2)
        assert document.tcp.position_mm == [1, 2, 151]
        assert document.method == "manual"
        assert document.controller is None
        again, same = versions.served_tcp(session, tool_id=tool["id"], fmt=None, if_none_match=etag)
        assert (again, same) == (None, etag)  # the client's copy is current


def test_the_tool_table_is_ordered_by_slot(api: Api) -> None:
    robot = api.robot("kr16", vendor="KUKA")
    late = api.tool(robot["id"], "a-torch", slot=7)
    early = api.tool(robot["id"], "z-gripper", slot=2)
    for tool in (late, early):
        api.manual(tool["id"], [0, 0, 150])
    table = api.get(f"/v1/robots/{robot['id']}/tool-table?format=kuka").json()
    assert [t["slot"] for t in table["items"]] == [2, 7]
    assert [t["tool_id"] for t in table["items"]] == [early["id"], late["id"]]


def test_a_cell_key_writes_versions_of_its_cell_only(api: Api) -> None:
    made = api.post("/v1/keys", {"name": "c12", "scope": "calibrate", "cells": ["cell-12"]})
    assert made.status_code == 201, made.text
    api.keys["c12"] = made.json()["key"]
    mine = api.tool(api.robot("r12", cell="cell-12")["id"])["id"]
    other = api.tool(api.robot("r7", cell="cell-7")["id"])["id"]
    body = {"method": "manual", "tcp": {"position_mm": [0, 0, 150]}}
    ok = api.post(f"/v1/tools/{mine}/calibrations", body, scope="c12")
    assert ok.status_code == 201, ok.text
    refused = api.post(f"/v1/tools/{other}/calibrations", body, scope="c12")
    assert refused.status_code == 404, refused.text
    assert api.get(f"/v1/tools/{other}/versions").json()["items"] == []
    assert api.get(f"/v1/tools/{mine}").json()["active_version"] == 1


def test_a_new_version_and_an_activation_refresh_the_stored_drift(api: Api) -> None:
    tool_id = api.tool(api.robot("kr16")["id"])["id"]
    api.manual(tool_id, [0, 0, 150])
    with session_scope(write=True) as session:  # a trend stored for v1, as a check stores it
        refresh_drift(session, get_tool(session, tool_id))
    api.manual(tool_id, [0, 0, 151])
    assert api.get(f"/v1/tools/{tool_id}/drift").json()["active_version"] == 2
    back = api.post(f"/v1/tools/{tool_id}/versions/1/activate", scope="calibrate")
    assert back.status_code == 200, back.text
    assert api.get(f"/v1/tools/{tool_id}/drift").json()["active_version"] == 1


def test_a_tool_read_in_the_calibrations_transaction_reads_its_new_counters_back(
    api: Api,
) -> None:
    """A calibration writes the tool's counters once, after its version and its activation
    (save_deferred): a Tool the transaction already holds (submit loads one itself to solve,
    a caller may hold another) must read them back, not keep the counters it loaded."""
    tool_id = api.tool(api.robot("kr16", vendor="KUKA")["id"])["id"]
    api.manual(tool_id, [0, 0, 150])
    body: dict[str, object] = {"method": "manual", "tcp": {"position_mm": [0, 0, 151]}}
    with session_scope(write=True) as session:
        held = get_tool(session, tool_id)
        assert (held.active_version, held.last_version) == (1, 1)
        stored, _ = writes.submit(
            session,
            tool_id=tool_id,
            request=CALIBRATION_REQUESTS.validate_python(body),
            raw_body=body,
            idempotency_key=None,
            actor=ACTOR,
        )
        assert (stored.version, stored.active) == (2, True)
        assert (held.active_version, held.last_version) == (2, 2)
        assert get_tool(session, tool_id).active_version == 2
