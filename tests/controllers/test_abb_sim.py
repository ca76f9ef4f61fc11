"""The ABB simulator's work objects (wobjdata) and a stationary tool against abb-robot-client
(RWS 1.0, a client others wrote, on PyPI) and by hand against RWS 2.0 with its mastership."""

from __future__ import annotations

import ssl

import httpx
import numpy as np
import pytest
from abb_robot_client.rws import RWS, ABBException
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from tests.controllers.abb_sim import AbbRwsSimulator, WobjSymbol, read_wobjdata
from tests.controllers.simbase import go_silent

USER, PASSWORD = "Default User", "robotics"
FIXTURE = '[FALSE,TRUE,"",[[800,-200,350],[1,0,0,0]],[[10,20,0],[0.7071068,0,0,0.7071068]]]'
#: a new uframe, the oframe and robhold as read
WRITTEN = (
    '[FALSE,TRUE,"",[[812.5,-190.25,351],[0.5,0.5,0.5,0.5]],[[10,20,0],[0.7071068,0,0,0.7071068]]]'
)
V2_HEADERS = {
    "Accept": "application/hal+json;v=2.0",
    "Content-Type": "application/x-www-form-urlencoded;v=2.0",
}


def held(sim: AbbRwsSimulator) -> tuple[dict[str, WobjSymbol], dict[str, object]]:
    """Every wobjdata and tooldata the controller holds (copies)."""
    return (
        {name: sim.wobj(name) for name in sim.wobjdata},
        {name: sim.tool(name) for name in sim.symbols},
    )


def test_abb_robot_client_reads_and_writes_a_wobjdata_touching_nothing_else(
    abb_rws1_sim: AbbRwsSimulator,
) -> None:
    sim = abb_rws1_sim
    wobjs_before, tools_before = held(sim)
    client = RWS(sim.base_url, USER, PASSWORD)
    assert client.get_rapid_variable("user/wobjFixture") == FIXTURE
    client.set_rapid_variable("user/wobjFixture", WRITTEN)
    assert client.get_rapid_variable("user/wobjFixture") == WRITTEN
    now = sim.wobj("T_ROB1/user/wobjFixture")
    assert now.uframe == ((812.5, -190.25, 351.0), (0.5, 0.5, 0.5, 0.5))
    assert now.oframe == wobjs_before["T_ROB1/user/wobjFixture"].oframe
    assert (now.robhold, now.ufprog, now.ufmec) == (False, True, "")
    wobjs_after, tools_after = held(sim)
    del wobjs_after["T_ROB1/user/wobjFixture"], wobjs_before["T_ROB1/user/wobjFixture"]
    assert wobjs_after == wobjs_before
    assert tools_after == tools_before


def test_the_rapid_manuals_example_wobjdata_is_taken_as_written(
    abb_rws1_sim: AbbRwsSimulator,
) -> None:
    example = (
        '[ FALSE, TRUE, "", [ [300, 600, 200], [1, 0, 0 ,0] ], [ [0, 200, 30], [1, 0, 0 ,0] ] ]'
    )
    RWS(abb_rws1_sim.base_url, USER, PASSWORD).set_rapid_variable("user/wobjTable", example)
    assert abb_rws1_sim.wobj("T_ROB1/user/wobjTable") == WobjSymbol(
        False,
        True,
        "",
        ((300.0, 600.0, 200.0), (1.0, 0.0, 0.0, 0.0)),
        ((0.0, 200.0, 30.0), (1.0, 0.0, 0.0, 0.0)),
    )
    assert read_wobjdata('[TRUE,FALSE,"ROB_2",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]]').ufmec == (
        "ROB_2"
    )


def test_a_wobjdata_write_of_the_wrong_type_or_shape_is_refused(
    abb_rws1_sim: AbbRwsSimulator,
) -> None:
    sim = abb_rws1_sim
    before = held(sim)
    client = RWS(sim.base_url, USER, PASSWORD)
    tooldata = "[TRUE,[[0,0,150],[1,0,0,0]],[2.5,[0,0,80],[1,0,0,0],0,0,0]]"
    with pytest.raises(ABBException, match="Invalid value for wobjdata"):
        client.set_rapid_variable("user/wobjTable", tooldata)
    with pytest.raises(ABBException, match="Invalid value for tooldata"):
        client.set_rapid_variable("user/tTorch", FIXTURE)
    with pytest.raises(ABBException, match=r"normalized quaternion.*oframe"):
        client.set_rapid_variable("user/wobjTable", FIXTURE.replace("0.7071068,0,0", "1,0,0"))
    with pytest.raises(ABBException, match="robhold and ufprog are bools"):
        client.set_rapid_variable("user/wobjTable", FIXTURE.replace("FALSE", "0", 1))
    with pytest.raises(ABBException, match="Symbol not found"):
        client.set_rapid_variable("user/wobjNothing", FIXTURE)
    assert held(sim) == before


def test_a_stationary_tool_keeps_robhold_false(abb_rws1_sim: AbbRwsSimulator) -> None:
    """tGripper is a stationary tool (robhold FALSE): its tframe is written as any tooldata's."""
    client = RWS(abb_rws1_sim.base_url, USER, PASSWORD)
    assert client.get_rapid_variable("user/tGripper").startswith("[FALSE,")
    client.set_rapid_variable(
        "user/tGripper", "[FALSE,[[1500,200,900],[0,1,0,0]],[2,[0,0,50],[1,0,0,0],0,0,0]]"
    )
    tool = abb_rws1_sim.tool("T_ROB1/user/tGripper")
    assert (tool.robhold, tool.trans, tool.rot) == (False, (1500.0, 200.0, 900.0), (0, 1, 0, 0))
    assert abb_rws1_sim.tool("T_ROB1/user/tTorch").robhold is True


def test_the_robtarget_in_a_written_work_object_is_seen_from_its_frame(
    abb_rws1_sim: AbbRwsSimulator,
) -> None:
    sim = abb_rws1_sim
    sim.base_frame = ((0.0, 0.0, 400.0), (1.0, 0.0, 0.0, 0.0))  # the robot on a riser
    client = RWS(sim.base_url, USER, PASSWORD)
    client.set_rapid_variable("user/wobjFixture", WRITTEN)
    # abb-robot-client's get_robtarget looks for "eaxa" where the manual says "eax_a"
    # (tests/vendors/abb/test_rws.py): the robtarget is asked by hand
    with httpx.Client(base_url=sim.base_url, auth=httpx.DigestAuth(USER, PASSWORD)) as http:
        answer = http.get(
            "/rw/motionsystem/mechunits/ROB_1/robtarget",
            params={"wobj": "wobjFixture", "coordinate": "Wobj", "json": "1"},
        )
    item = answer.json()["_embedded"]["_state"][0]
    # the test's own: wobj = uframe * oframe in the world, flange in the base
    uframe = _matrix((812.5, -190.25, 351.0), (0.5, 0.5, 0.5, 0.5))
    oframe = _matrix((10.0, 20.0, 0.0), (0.7071068, 0.0, 0.0, 0.7071068))
    flange = _matrix(*sim.flange)
    base = _matrix((0.0, 0.0, 400.0), (1.0, 0.0, 0.0, 0.0))
    expected = np.linalg.inv(uframe @ oframe) @ base @ flange
    assert_allclose([float(item[k]) for k in "xyz"], expected[:3, 3], atol=1e-3)


def _matrix(trans: tuple[float, ...], q: tuple[float, ...]) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()
    m[:3, 3] = trans
    return m


@pytest.mark.parametrize(("moment", "new"), [("before", False), ("after", True)])
def test_silence_around_a_wobjdata_write(
    abb_rws1_sim: AbbRwsSimulator, moment: str, new: bool
) -> None:
    """Cut before the write: no answer, the old work object; after it: no answer, the new."""
    sim = abb_rws1_sim
    path = "/rw/rapid/symbol/data/RAPID/T_ROB1/user/wobjFixture"
    sim.fault = go_silent(moment, f"POST {path}")  # type: ignore[arg-type]
    auth = httpx.DigestAuth(USER, PASSWORD)
    with (
        httpx.Client(base_url=sim.base_url, auth=auth, timeout=0.5) as client,
        pytest.raises(httpx.ReadTimeout),
    ):
        client.post(path, params={"action": "set", "json": "1"}, data={"value": WRITTEN})
    sim.stalled = False
    expected = WRITTEN if new else FIXTURE
    assert RWS(sim.base_url, USER, PASSWORD).get_rapid_variable("user/wobjFixture") == expected


@pytest.mark.filterwarnings("ignore::urllib3.exceptions.InsecureRequestWarning")
def test_rws2_writes_a_wobjdata_only_under_edit_mastership(
    abb_rws2_sim: AbbRwsSimulator,
) -> None:
    sim = abb_rws2_sim
    path = "/rw/rapid/symbol/RAPID/T_ROB1/user/wobjTable/data"
    with httpx.Client(
        base_url=sim.base_url,
        auth=(USER, PASSWORD),
        verify=ssl.create_default_context(cafile=str(sim.certificate_path)),
        headers=V2_HEADERS,
        timeout=2,
    ) as client:
        refused = client.post(path, data={"value": FIXTURE})
        assert refused.status_code == 403
        assert "edit mastership is required" in refused.json()["status"]["msg"]
        assert sim.wobj("T_ROB1/user/wobjTable") == WobjSymbol()
        sim.mastership_holder = "FlexPendant"
        assert client.post("/rw/mastership/edit/request").status_code == 403
        sim.mastership_holder = None
        assert client.post("/rw/mastership/edit/request").status_code == 204
        assert client.post(path, data={"value": FIXTURE}).status_code == 204
        assert client.post("/rw/mastership/edit/release").status_code == 204
        read = client.get(path).json()["state"][0]["value"]
    assert read == FIXTURE
    assert sim.wobj("T_ROB1/user/wobjTable") == sim.wobj("T_ROB1/user/wobjFixture")
    assert sim.wobj("T_ROB2/user/wobjTable") == WobjSymbol()
