"""Keys limited to robot cells: a cell-12 key finds only cell-12's robots and their tools.
Everything of cell 7 answers exactly as an id nobody issued (same status, type and words),
lists and the CSV hold only cell-12 rows, and the key cannot put a robot outside its cells."""

from __future__ import annotations

from typing import Any
from uuid import uuid4

import numpy as np
import pytest

from tests.api.test_audit_every_write import POINT, TCP, _touch_at_point, _touches
from tests.conftest import Api

CELL12, CELL7 = "cell-12", "cell-7"


def _cell_world(api: Api, cell: str) -> dict[str, str]:
    """A robot of `cell` with a calibrated tool, a reference point, a laser device, a guided
    session with a touch, and a tool archived since."""
    robot = api.robot(f"robot-{cell}", cell=cell)["id"]
    tool = api.tool(robot, "torch", slot=1)["id"]
    calibration = api.manual(tool, TCP)["id"]
    point = api.post(f"/v1/robots/{robot}/reference-points", {"name": "pin", "position_mm": POINT})
    device = api.post(
        f"/v1/robots/{robot}/laser-devices",
        {"name": "beams", "beam_a_y_mm": 1.0, "beam_b_x_mm": 2.0, "plane_z_mm": 3.0},
    )
    session = api.post(f"/v1/tools/{tool}/sessions", {"method": "xyz_npoint", "format": "kuka_abc"})
    sid = session.json()["id"]
    assert api.post(f"/v1/sessions/{sid}/poses", {"pose": _touches()[0]}).status_code == 200
    archived = api.tool(robot, "old-torch", slot=2)["id"]
    assert api.delete(f"/v1/tools/{archived}").status_code == 204
    return {
        "robot": robot,
        "tool": tool,
        "calibration": calibration,
        "point": point.json()["id"],
        "device": device.json()["id"],
        "session": sid,
        "archived": archived,
    }


def _two_cells(api: Api) -> dict[str, dict[str, str]]:
    """Cells 12 and 7, and keys of each scope limited to cell 12 (api scopes c12-<scope>)."""
    world = {CELL12: _cell_world(api, CELL12), CELL7: _cell_world(api, CELL7)}
    for scope in ("read", "calibrate", "admin"):
        made = api.post("/v1/keys", {"name": f"c12-{scope}", "scope": scope, "cells": [CELL12]})
        assert made.status_code == 201, made.text
        assert made.json()["cells"] == [CELL12]
        api.keys[f"c12-{scope}"] = made.json()["key"]
    return world


@pytest.fixture
def cells(api: Api) -> dict[str, dict[str, str]]:
    """The two cells and their keys: built by the module's first test on each backend, put
    back as they were for every other (Api.world), not built again by each of ~45 cases."""
    return api.world(_two_cells)


#: Reads of one thing of cell 7 by id: (url template, what the id names).
READS = [
    ("/v1/robots/{robot}", "robot"),
    ("/v1/robots/{robot}/tools", "robot"),
    ("/v1/robots/{robot}/tool-table", "robot"),
    ("/v1/robots/{robot}/reference-points", "robot"),
    ("/v1/robots/{robot}/reference-points/{point}", "robot"),
    ("/v1/robots/{robot}/laser-devices", "robot"),
    ("/v1/robots/{robot}/laser-devices/{device}", "robot"),
    ("/v1/tools/{tool}", "tool"),
    ("/v1/tools/{archived}", "archived"),
    ("/v1/tools/{tool}/tcp", "tool"),
    ("/v1/tools/{tool}/tcp?format=kuka", "tool"),
    ("/v1/tools/{tool}/versions", "tool"),
    ("/v1/tools/{tool}/versions/1", "tool"),
    ("/v1/tools/{tool}/calibrations", "tool"),
    ("/v1/tools/{tool}/checks", "tool"),
    ("/v1/calibrations/{calibration}", "calibration"),
    ("/v1/sessions/{session}", "session"),
]


def _as_if_absent(
    api: Api, method: str, template: str, ids: dict[str, str], named: str, scope: str, **kw: Any
) -> None:
    """`template` with cell 7's ids answers as it does with an id nobody issued."""
    real = api.request(method, template.format(**ids), scope, **kw)
    fake_ids = {**ids, named: str(uuid4())}
    fake = api.request(method, template.format(**fake_ids), scope, **kw)
    assert real.status_code == fake.status_code == 404, (template, real.text, fake.text)
    assert real.headers["content-type"] == fake.headers["content-type"]
    real_doc, fake_doc = real.json(), fake.json()
    real_doc["detail"] = real_doc["detail"].replace(ids[named], fake_ids[named])
    assert real_doc == fake_doc, template


@pytest.mark.parametrize(("template", "named"), READS, ids=[r[0] for r in READS])
def test_another_cells_things_are_absent_to_a_cell_key(
    api: Api, cells: dict[str, dict[str, str]], template: str, named: str
) -> None:
    ids = cells[CELL7]
    _as_if_absent(api, "GET", template, ids, named, "c12-read")
    # ...and present to the cell's own key, and to a key of every cell.
    own = api.get(template.format(**cells[CELL12]), scope="c12-read")
    if named != "archived":
        assert own.status_code == 200, (template, own.text)
        assert api.get(template.format(**ids), scope="read").status_code == 200


@pytest.mark.parametrize(
    ("template", "named"),
    [
        ("/v1/tools/{tool}/tcp?format=kuka", "tool"),
        ("/v1/robots/{robot}/tool-table?format=kuka", "robot"),
    ],
)
def test_another_cells_controller_files_are_absent_to_a_cell_key(
    api: Api, cells: dict[str, dict[str, str]], template: str, named: str
) -> None:
    """The controller files (Accept: text/plain) have a held read of their own."""
    text = {"headers": {"Accept": "text/plain"}}
    _as_if_absent(api, "GET", template, cells[CELL7], named, "c12-read", **text)
    own = api.get(template.format(**cells[CELL12]), scope="c12-read", **text)
    assert own.status_code == 200, own.text
    assert own.headers["content-type"].startswith("text/plain")


WRITES = [
    ("PATCH", "/v1/robots/{robot}", "robot", {"name": "mine now"}),
    ("DELETE", "/v1/robots/{robot}", "robot", None),
    ("POST", "/v1/robots/{robot}/tools", "robot", {"name": "x"}),
    ("POST", "/v1/robots/{robot}/reference-points", "robot", {"name": "p", "position_mm": POINT}),
    (
        "POST",
        "/v1/robots/{robot}/laser-devices",
        "robot",
        {"name": "b", "beam_a_y_mm": 1.0, "beam_b_x_mm": 2.0, "plane_z_mm": 3.0},
    ),
    ("PATCH", "/v1/tools/{tool}", "tool", {"tolerance": {"max_rms_mm": 9.0}}),
    ("DELETE", "/v1/tools/{tool}", "tool", None),
    (
        "POST",
        "/v1/tools/{tool}/calibrations",
        "tool",
        {"method": "manual", "tcp": {"position_mm": [1, 2, 3]}},
    ),
    ("POST", "/v1/tools/{tool}/versions/1/activate", "tool", None),
    ("POST", "/v1/tools/{tool}/sessions", "tool", {"method": "xyz_npoint", "format": "kuka_abc"}),
    ("POST", "/v1/sessions/{session}/poses", "session", {"pose": [800, 0, 300, 0, 180, 0]}),
    ("DELETE", "/v1/sessions/{session}/poses/0", "session", None),
    ("POST", "/v1/sessions/{session}/finish", "session", {}),
]


@pytest.mark.parametrize(
    ("method", "template", "named", "body"), WRITES, ids=[f"{w[0]} {w[1]}" for w in WRITES]
)
def test_another_cells_things_cannot_be_changed_by_a_cell_key(
    api: Api,
    cells: dict[str, dict[str, str]],
    method: str,
    template: str,
    named: str,
    body: Any,
) -> None:
    trail_before = api.get("/v1/audit", scope="admin", params={"limit": 500}).json()["items"]
    kw = {} if body is None else {"json": body}
    _as_if_absent(api, method, template, cells[CELL7], named, "c12-admin", **kw)
    trail_after = api.get("/v1/audit", scope="admin", params={"limit": 500}).json()["items"]
    assert trail_after == trail_before  # nothing changed, nothing recorded


def test_a_check_of_another_cells_tool_is_absent(
    api: Api, cells: dict[str, dict[str, str]]
) -> None:
    ids = cells[CELL7]
    body = {"reference_point_id": ids["point"], "format": "xyz_wxyz", "poses": [_touch_at_point()]}
    assert api.post(f"/v1/tools/{ids['tool']}/checks", body, scope="read").status_code == 403
    _as_if_absent(api, "POST", "/v1/tools/{tool}/checks", ids, "tool", "c12-calibrate", json=body)
    # the same check of the cell's own tool goes through
    own = cells[CELL12]
    body["reference_point_id"] = own["point"]
    done = api.post(f"/v1/tools/{own['tool']}/checks", body, scope="c12-calibrate")
    assert done.status_code == 200, done.text


def test_lists_and_the_csv_hold_only_the_keys_cells(
    api: Api, cells: dict[str, dict[str, str]]
) -> None:
    robots = api.get("/v1/robots", scope="c12-read").json()["items"]
    assert [r["cell"] for r in robots] == [CELL12]
    fleet = api.get("/v1/tools", scope="c12-read").json()["items"]
    assert [(t["cell"], t["name"]) for t in fleet] == [(CELL12, "torch")]
    assert api.get("/v1/tools", scope="c12-read", params={"cell": CELL7}).json()["items"] == []
    csv = api.get("/v1/tools", scope="c12-read", headers={"Accept": "text/csv"}).text
    lines = csv.strip().splitlines()
    assert len(lines) == 2
    assert CELL12 in lines[1]
    assert CELL7 not in csv
    everyone = api.get("/v1/tools", scope="read", headers={"Accept": "text/csv"}).text
    assert len(everyone.strip().splitlines()) == 3


def test_a_cell_key_cannot_put_a_robot_outside_its_cells(
    api: Api, cells: dict[str, dict[str, str]]
) -> None:
    for body in ({"name": "new", "cell": CELL7}, {"name": "new"}):
        refused = api.post("/v1/robots", body, scope="c12-admin")
        assert refused.status_code == 403, refused.text
        assert refused.json()["errors"][0]["loc"] == ["body", "cell"]
        assert CELL12 in refused.json()["detail"]
    assert (
        api.post("/v1/robots", {"name": "new", "cell": CELL12}, scope="c12-admin").status_code
        == 201
    )
    own = cells[CELL12]["robot"]
    moved = api.patch(f"/v1/robots/{own}", {"cell": CELL7}, scope="c12-admin")
    assert moved.status_code == 403, moved.text
    assert api.get(f"/v1/robots/{own}", scope="read").json()["cell"] == CELL12
    assert [r["cell"] for r in api.get("/v1/robots", scope="c12-read").json()["items"]] == [
        CELL12,
        CELL12,
    ]


def test_plan_and_solve_do_not_find_another_cells_tool_or_robot(
    api: Api, cells: dict[str, dict[str, str]]
) -> None:
    plan = {"format": "kuka_abc", "start": _touches()[0], "tool_id": cells[CELL7]["tool"]}
    hidden = api.post("/v1/plan", plan, scope="c12-read")
    unknown = api.post("/v1/plan", {**plan, "tool_id": str(uuid4())}, scope="c12-read")
    assert hidden.status_code == unknown.status_code == 422
    assert hidden.json()["type"] == unknown.json()["type"]
    assert api.post("/v1/plan", plan, scope="read").status_code == 200
    own = api.post("/v1/plan", {**plan, "tool_id": cells[CELL12]["tool"]}, scope="c12-read")
    assert own.status_code == 200, own.text

    solve = {"method": "xyz_npoint", "format": "kuka_abc", "poses": _touches()}
    robot7, nobody = cells[CELL7]["robot"], str(uuid4())
    hidden = api.post("/v1/solve", {**solve, "robot_id": robot7}, scope="c12-read")
    unknown = api.post("/v1/solve", {**solve, "robot_id": nobody}, scope="c12-read")
    assert hidden.status_code == unknown.status_code == 404
    assert hidden.json()["detail"].replace(robot7, nobody) == unknown.json()["detail"]
    assert api.post("/v1/solve", {**solve, "robot_id": robot7}, scope="read").status_code == 200


def test_a_cell_keys_calibration_of_another_cells_tool_is_absent_also_in_the_solver(
    api: Api, cells: dict[str, dict[str, str]]
) -> None:
    """The N-point path: the snapshot is read on the event loop, the write happens in a
    solver process; both find only the key's cells."""
    body = {"method": "xyz_npoint", "format": "kuka_abc", "poses": _touches(8)}
    tool7 = cells[CELL7]["tool"]
    hidden = api.post(f"/v1/tools/{tool7}/calibrations", body, scope="c12-calibrate")
    assert hidden.status_code == 404, hidden.text
    assert hidden.json()["detail"] == f"no tool with id {tool7}"
    own = api.post(f"/v1/tools/{cells[CELL12]['tool']}/calibrations", body, scope="c12-calibrate")
    assert own.status_code == 201, own.text
    assert np.allclose(own.json()["tcp"]["position_mm"], TCP, atol=0.2)


def test_a_cell_key_makes_and_sees_only_keys_of_its_cells(
    api: Api, cells: dict[str, dict[str, str]]
) -> None:
    for cells_asked in (None, [CELL7], [CELL12, CELL7]):
        body: dict[str, Any] = {"name": "k", "scope": "read"}
        if cells_asked is not None:
            body["cells"] = cells_asked
        refused = api.post("/v1/keys", body, scope="c12-admin")
        assert refused.status_code == 403, refused.text
        assert refused.json()["errors"][0]["loc"] == ["body", "cells"]
    made = api.post(
        "/v1/keys", {"name": "k", "scope": "read", "cells": [CELL12]}, scope="c12-admin"
    )
    assert made.status_code == 201, made.text
    listed = api.get("/v1/keys", scope="c12-admin").json()["items"]
    assert {k["cells"][0] for k in listed} == {CELL12}
    assert len(listed) == 4  # the three of the fixture and this one
    everyone = [k for k in api.get("/v1/keys", scope="admin").json()["items"] if not k["cells"]]
    unscoped = everyone[0]["id"]
    gone = api.delete(f"/v1/keys/{unscoped}", scope="c12-admin")
    assert gone.status_code == 404
    assert gone.json()["detail"] == f"no API key with id {unscoped}"
    # the trail of a cell key's admin: its cells' events only
    trail = api.get("/v1/audit", scope="c12-admin", params={"limit": 500}).json()["items"]
    assert trail
    assert {e["robot_id"] for e in trail} == {cells[CELL12]["robot"]}


@pytest.mark.parametrize(
    "cells_sent",
    ["cell-12", [], [""], [1], [" padded "], [None], ["x" * 201], {"cell": "cell-12"}],
)
def test_cells_must_be_a_list_of_names(api: Api, cells_sent: Any) -> None:
    before = api.get("/v1/keys", scope="admin").json()["items"]
    refused = api.post("/v1/keys", {"name": "k", "scope": "read", "cells": cells_sent})
    assert refused.status_code == 422, refused.text
    problem = refused.json()
    assert refused.headers["content-type"].startswith("application/problem+json")
    assert problem["errors"][0]["loc"][:2] == ["body", "cells"], problem
    assert api.get("/v1/keys", scope="admin").json()["items"] == before


#: This round's routes of a robot's controller, its tools' deployments and drift, as a cell
#: key would call them on cell 7's things: (method, url template, what the id names, body).
CONTROLLER_ROUTES: list[tuple[str, str, str, Any]] = [
    ("GET", "/v1/robots/{robot}/controller", "robot", None),
    ("PUT", "/v1/robots/{robot}/controller", "robot", {"protocol": "kuka_kvp", "host": "h"}),
    ("DELETE", "/v1/robots/{robot}/controller", "robot", None),
    ("POST", "/v1/robots/{robot}/reconcile", "robot", None),
    ("GET", "/v1/tools/{tool}/deployments", "tool", None),
    ("POST", "/v1/tools/{tool}/deployments", "tool", {}),
    ("GET", "/v1/tools/{tool}/drift", "tool", None),
]


@pytest.mark.parametrize(
    ("method", "template", "named", "body"),
    CONTROLLER_ROUTES,
    ids=[r[1] for r in CONTROLLER_ROUTES],
)
def test_another_cells_controller_deployments_and_drift_are_absent_to_a_cell_key(
    api: Api, cells: dict[str, dict[str, str]], method: str, template: str, named: str, body: Any
) -> None:
    ids = cells[CELL7]
    # Cell 7's robot has a controller (unreachable: nothing here talks to it).
    put = api.request(
        "PUT",
        f"/v1/robots/{ids['robot']}/controller",
        "admin",
        json={"protocol": "kuka_kvp", "host": "127.0.0.1", "port": 9, "timeout_s": 0.1},
    )
    assert put.status_code == 200, put.text
    before = api.get(f"/v1/robots/{ids['robot']}/controller", scope="admin").json()
    kw = {} if body is None else {"json": body}
    _as_if_absent(api, method, template, ids, named, "c12-admin", **kw)
    assert api.get(f"/v1/robots/{ids['robot']}/controller", scope="admin").json() == before
    deployments = api.get(f"/v1/tools/{ids['tool']}/deployments", scope="admin").json()
    assert deployments["items"] == []  # the cell key's POST made no attempt
