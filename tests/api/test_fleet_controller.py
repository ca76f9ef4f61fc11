"""The fleet's `controller`: a pendant edit of orientation alone is told in degrees.

Issue 37: a FANUC `UTOOL[3]` W edited by +0.5 deg at the pendant was `drifted` with
`deviation_mm` 0.000 and nothing else, so the fleet said "drifted 0.000 mm"."""

from __future__ import annotations

import csv
import io

import pytest

from tests.api.controller_rigs import SLOT, rig
from tests.api.test_deployments import ACTIVE_POSITION, ACTIVE_Q, _setup
from tests.conftest import Api

#: The pendant edit: W (rotation about the tool's x axis, applied first) + 0.5 deg.
W_EDIT_DEG = 0.5


def test_an_orientation_only_pendant_edit_is_in_the_fleets_deviation_deg(api: Api) -> None:
    with rig("fanuc_rmi") as r:
        ids = _setup(api, r)
        robot_id, tool_id = ids["robot"]["id"], ids["tool"]["id"]
        r.set_behind_back(ACTIVE_POSITION, ACTIVE_Q)
        x, y, z, w, p, rr = r.native_of(ACTIVE_POSITION, ACTIVE_Q)
        r.sim.set_tool(SLOT, x, y, z, w + W_EDIT_DEG, p, rr)
        found = api.post(f"/v1/robots/{robot_id}/reconcile", {})
        assert found.status_code == 200, found.text
        assert found.json()["state"] == "drifted"

    row = api.get("/v1/tools", params={"robot_id": robot_id}).json()["items"][0]
    controller = row["controller"]
    assert controller["state"] == "drifted"
    assert controller["deviation_mm"] == pytest.approx(0.0, abs=1e-3)
    assert controller["deviation_deg"] == pytest.approx(W_EDIT_DEG, abs=1e-3)

    response = api.get("/v1/tools", params={"robot_id": robot_id}, headers={"Accept": "text/csv"})
    assert response.status_code == 200
    (line,) = csv.DictReader(io.StringIO(response.text))
    assert line["tool_id"] == tool_id
    assert line["controller_state"] == "drifted"
    assert line["controller_deviation_mm"] == "0.0000"
    assert line["controller_deviation_deg"] == "0.5000"


def test_a_tool_never_compared_has_no_deviation_deg(api: Api) -> None:
    """Unreachable at the last look: no frame was read, so neither deviation is a number."""
    with rig("fanuc_rmi") as r:
        ids = _setup(api, r)
        robot_id = ids["robot"]["id"]
        r.sim.stop()
        found = api.post(f"/v1/robots/{robot_id}/reconcile", {})
        assert found.json()["state"] == "unreachable"
    controller = api.get("/v1/tools", params={"robot_id": robot_id}).json()["items"][0][
        "controller"
    ]
    assert controller["state"] == "unreachable"
    assert controller["deviation_mm"] is None
    assert controller["deviation_deg"] is None
