"""The ABB RWS 1.0 / 2.0 connector against the RWS simulator, and the RWS 1.0 simulator
against abb-robot-client (a client others wrote from the same manual)."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator

import httpx
import numpy as np
import pytest
from numpy.testing import assert_allclose

from app.vendors.abb.rws import AbbRwsConnector
from app.vendors.abb.text import RapidSyntaxError, format_tooldata, parse_tooldata
from app.vendors.connector import (
    ControllerProtocolError,
    ControllerRefused,
    ControllerSettings,
    ControllerSilent,
    ControllerUnreachable,
    LiveTool,
    ToolTarget,
)
from app.vendors.registry import connect
from app.vendors.tool import ToolData, ToolLoad
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fixtures import abb_settings
from tests.controllers.helpers import angle_between_deg, float32_tolerance, random_tool
from tests.controllers.simbase import go_silent

TORCH = ToolTarget(symbol="T_ROB1/user/tTorch")
GRIPPER = ToolTarget(symbol="T_ROB1/user/tGripper")
SECRET = "s3cret-Pa55word!"


@pytest.fixture(params=[1, 2], ids=["rws1", "rws2"])
def sim(request: pytest.FixtureRequest) -> Iterator[AbbRwsSimulator]:
    with AbbRwsSimulator(version=request.param) as simulator:
        yield simulator


@pytest.mark.parametrize("version", [1, 2])
@pytest.mark.parametrize("seed", range(4))
def test_written_tool_is_held_as_a_quaternion_and_reads_back_to_1e6(
    version: int, seed: int
) -> None:
    tool = random_tool(seed)
    assert tool.load is not None
    with AbbRwsSimulator(version, single_precision=False) as sim, connect(abb_settings(sim)) as abb:
        abb.write_tool(GRIPPER, tool)
        held = sim.tool("T_ROB1/user/tGripper")
        back = abb.read_tool(GRIPPER)
    assert_allclose(held.trans, tool.position_mm, atol=1e-6)
    assert_allclose(held.rot, tool.quaternion, atol=1e-9)
    assert_allclose(held.mass, tool.load.mass_kg, atol=1e-6)
    assert_allclose(held.cog, tool.load.cog_or_origin, atol=1e-6)
    assert held.robhold is False, "the controller's robhold was kept"
    assert held.aom == (1.0, 0.0, 0.0, 0.0)
    assert_allclose(back.position_mm, tool.position_mm, atol=1e-6)
    assert angle_between_deg(back.quaternion, tool.quaternion) < 1e-6
    assert sim.tool("T_ROB1/user/tTorch").trans == (0.0, 0.0, 0.0), "another symbol changed"


def test_a_controller_holding_32_bit_nums_reads_back_within_its_resolution(
    sim: AbbRwsSimulator,
) -> None:
    tool = random_tool(7)
    with connect(abb_settings(sim)) as abb:
        abb.write_tool(TORCH, tool)
        back = abb.read_tool(TORCH)
    assert_allclose(
        sim.tool("T_ROB1/user/tTorch").trans,
        tool.position_mm,
        atol=float32_tolerance(tool.position_mm),
    )
    assert_allclose(back.position_mm, tool.position_mm, atol=1e-3)
    assert angle_between_deg(back.quaternion, tool.quaternion) < 1e-3


def test_a_write_without_load_keeps_the_controllers_tload(sim: AbbRwsSimulator) -> None:
    sim.set_tool("T_ROB1/user/tGripper", (0, 0, 10), (1, 0, 0, 0), mass=4.5, cog=(1.0, 2.0, 60.0))
    with connect(abb_settings(sim)) as abb:
        abb.write_tool(GRIPPER, ToolData((5.0, 6.0, 250.0), (0.0, 0.0, 0.0, 1.0), None))
        back = abb.read_tool(GRIPPER)
    assert back.position_mm == (5.0, 6.0, 250.0)
    assert back.quaternion == (0.0, 0.0, 0.0, 1.0)
    assert back.load == ToolLoad(4.5, (1.0, 2.0, 60.0))


def test_what_the_operator_enters_on_the_flexpendant_is_read(sim: AbbRwsSimulator) -> None:
    sim.set_tool("T_ROB2/user/tTorch", (12.5, 0.0, 180.0), (0.5, 0.5, 0.5, 0.5), mass=1.25)
    with connect(abb_settings(sim)) as abb:
        tool = abb.read_tool(ToolTarget(symbol="T_ROB2/user/tTorch"))
        assert abb.describe(ToolTarget(symbol="T_ROB2/user/tTorch")) == "T_ROB2/user/tTorch"
    assert tool.position_mm == (12.5, 0.0, 180.0)
    assert tool.quaternion == (0.5, 0.5, 0.5, 0.5)
    assert tool.load == ToolLoad(1.25, (0.0, 0.0, 1.0))


def test_an_unknown_symbol_is_refused_in_the_controllers_words(sim: AbbRwsSimulator) -> None:
    with connect(abb_settings(sim)) as abb:
        with pytest.raises(ControllerRefused) as err:
            abb.read_tool(ToolTarget(symbol="T_ROB1/user/tNothing"))
        assert "Symbol not found: RAPID/T_ROB1/user/tNothing" in err.value.controller_message
        with pytest.raises(ControllerRefused, match="not a tooldata") as not_tool:
            abb.write_tool(ToolTarget(symbol="T_ROB1/user/reg1"), ToolData((0, 0, 1), (1, 0, 0, 0)))
        assert not_tool.value.controller_message == "T_ROB1/user/reg1 = 0"
    assert sim.mastership_holder is None


def test_a_wrong_password_is_refused_and_never_repeated(
    sim: AbbRwsSimulator, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG)
    settings = abb_settings(sim, password=SECRET)
    with pytest.raises(ControllerRefused, match="credentials") as err, connect(settings) as abb:
        abb.read_tool(TORCH)
    assert "401" in err.value.controller_message
    texts = [
        str(err.value),
        repr(err.value),
        err.value.controller_message,
        repr(settings),
        str(settings),
    ]
    texts += [record.getMessage() for record in caplog.records]
    assert all(SECRET not in text for text in texts)
    assert sim.requests
    assert sim.sessions == {}


def test_each_session_logs_out(sim: AbbRwsSimulator) -> None:
    with connect(abb_settings(sim)) as abb:
        abb.read_tool(TORCH)
        abb.write_tool(TORCH, ToolData((0, 0, 5), (1, 0, 0, 0)))
        abb.read_tool(TORCH)
        assert len(sim.sessions) == 1, "one controller session, its cookie sent back"
    assert sim.sessions == {}
    assert sim.requests[-1][:2] == ("GET", "/logout")


def test_rws2_writes_under_edit_mastership_and_releases_it() -> None:
    with AbbRwsSimulator(2) as sim, connect(abb_settings(sim)) as abb:
        abb.write_tool(TORCH, ToolData((0, 0, 99), (1, 0, 0, 0)))
        paths = [path for method, path, _ in sim.requests if method == "POST"]
        assert paths == [
            "/rw/mastership/edit/request",
            "/rw/rapid/symbol/RAPID/T_ROB1/user/tTorch/data",
            "/rw/mastership/edit/release",
        ]
        assert sim.mastership_holder is None
        # A write the controller refuses (|q| = 2) releases mastership too.
        with pytest.raises(ControllerRefused, match="Not a normalized quaternion"):
            abb.write_tool(TORCH, ToolData((0, 0, 1), (2.0, 0.0, 0.0, 0.0)))
        assert [path for method, path, _ in sim.requests if method == "POST"][-1] == (
            "/rw/mastership/edit/release"
        )
    assert sim.mastership_holder is None


def test_rws2_refuses_a_write_while_the_flexpendant_holds_mastership() -> None:
    with AbbRwsSimulator(2) as sim:
        sim.mastership_holder = "FlexPendant"
        with connect(abb_settings(sim)) as abb, pytest.raises(ControllerRefused) as err:
            abb.write_tool(TORCH, ToolData((0, 0, 99), (1, 0, 0, 0)))
        assert "Mastership is held by another client (FlexPendant)" in err.value.controller_message
        assert sim.tool("T_ROB1/user/tTorch").trans == (0.0, 0.0, 0.0)
        assert sim.mastership_holder == "FlexPendant"


def test_rws2_simulator_refuses_a_write_without_mastership_and_unversioned_media() -> None:
    with (
        AbbRwsSimulator(2) as sim,
        httpx.Client(
            base_url=sim.base_url, auth=("Default User", "robotics"), verify=False
        ) as client,
    ):
        path = "/rw/rapid/symbol/RAPID/T_ROB1/user/tTorch/data"
        v2 = {"Accept": "application/hal+json;v=2.0"}
        form = {**v2, "Content-Type": "application/x-www-form-urlencoded;v=2.0"}
        value = {"value": "[TRUE,[[0,0,1],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]]"}
        refused = client.post(path, headers=form, data=value)
        assert refused.status_code == 403
        assert "edit mastership is required" in refused.json()["status"]["msg"]
        assert client.get(path, headers={"Accept": "application/json"}).status_code == 406
        missing = client.post(path, headers=form, data={})
        assert missing.json()["status"] == {
            "code": -1073445879,
            "msg": "Data parameter is required",
        }
        assert (
            client.post(
                path,
                headers={**v2, "Content-Type": "application/x-www-form-urlencoded"},
                data=value,
            ).status_code
            == 415
        )
        assert client.post("/rw/mastership/edit/request", headers=form).status_code == 204
        assert client.post(path, headers=form, data=value).status_code == 204
    assert sim.tool("T_ROB1/user/tTorch").trans == (0.0, 0.0, 1.0)


def test_rws2_with_tls_verify_refuses_an_untrusted_certificate() -> None:
    with AbbRwsSimulator(2) as sim:
        settings = abb_settings(sim)
        strict = ControllerSettings(**{**settings.__dict__, "tls_verify": True})
        with pytest.raises(ControllerUnreachable, match="certificate"), connect(strict) as abb:
            abb.read_tool(TORCH)


def test_rws2_with_tls_verify_trusts_a_certificate_the_plant_installed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    with AbbRwsSimulator(2) as sim:
        assert sim.certificate_path is not None
        monkeypatch.setenv("SSL_CERT_FILE", str(sim.certificate_path))
        strict = ControllerSettings(**{**abb_settings(sim).__dict__, "tls_verify": True})
        with connect(strict) as abb:
            assert abb.read_tool(TORCH).position_mm == (0.0, 0.0, 0.0)


def test_rws1_is_plain_http_with_digest() -> None:
    with AbbRwsSimulator(1) as sim, connect(abb_settings(sim)) as abb:
        abb.read_tool(TORCH)
        assert [scheme for _, _, scheme in sim.requests] == ["", "Digest"]


def test_a_stopped_controller_is_unreachable(sim: AbbRwsSimulator) -> None:
    settings = abb_settings(sim)
    sim.stop()
    started = time.monotonic()
    with pytest.raises(ControllerUnreachable, match="cannot connect"), connect(settings) as abb:
        abb.read_tool(TORCH)
    assert time.monotonic() - started < settings.timeout_s


def test_a_controller_that_never_answers_fails_within_the_timeout(sim: AbbRwsSimulator) -> None:
    sim.stalled = True
    settings = abb_settings(sim, timeout_s=0.5)
    started = time.monotonic()
    silent = pytest.raises(ControllerSilent, match="accepted the TCP connection and sent nothing")
    with silent, connect(settings) as abb:
        abb.write_tool(TORCH, ToolData((0, 0, 1), (1, 0, 0, 0)))
    elapsed = time.monotonic() - started
    assert settings.timeout_s * 0.9 <= elapsed < settings.timeout_s + 1.0, elapsed


def test_tooldata_text_round_trips_and_refuses_what_is_not_one() -> None:
    text = "[TRUE,[[0,0,150],[1,0,0,0]],[2.5,[0,0,80],[1,0,0,0],0,0,0]]"
    tool = parse_tooldata(text)
    assert tool.position_mm == (0.0, 0.0, 150.0)
    assert tool.mass_kg == 2.5
    assert format_tooldata(tool) == text
    spaced = parse_tooldata(
        " [ FALSE , [[1E-05,2,3],[0.5,0.5,0.5,0.5]],[-1,[0,0,0],[1,0,0,0],0,0,0] ] "
    )
    assert spaced.robhold is False
    assert spaced.position_mm[0] == 1e-5
    for bad in (
        "0",
        "[TRUE,[[0,0],[1,0,0,0]],[1,[0,0,0],[1,0,0,0],0,0,0]]",
        "[TRUE,[[0,0,0],[1,0,0,0]]",
        "[1,[[0,0,0],[1,0,0,0]],[1,[0,0,0],[1,0,0,0],0,0,0]]",
    ):
        with pytest.raises(RapidSyntaxError):
            parse_tooldata(bad)


def test_abb_robot_client_reads_and_writes_the_rws1_simulator(
    abb_rws1_sim: AbbRwsSimulator,
) -> None:
    from abb_robot_client.rws import RWS, ABBException

    abb_rws1_sim.set_tool(
        "T_ROB1/user/tTorch",
        (0.0, 0.0, 150.0),
        (1.0, 0.0, 0.0, 0.0),
        mass=2.5,
        cog=(0.0, 0.0, 80.0),
    )
    client = RWS(abb_rws1_sim.base_url, "Default User", "robotics")
    assert (
        client.get_rapid_variable("user/tTorch")
        == "[TRUE,[[0,0,150],[1,0,0,0]],[2.5,[0,0,80],[1,0,0,0],0,0,0]]"
    )
    client.set_rapid_variable(
        "user/tTorch", "[TRUE,[[1,2,3],[0,1,0,0]],[2.5,[0,0,80],[1,0,0,0],0,0,0]]"
    )
    assert abb_rws1_sim.tool("T_ROB1/user/tTorch").trans == (1.0, 2.0, 3.0)
    assert abb_rws1_sim.tool("T_ROB1/user/tTorch").rot == (0.0, 1.0, 0.0, 0.0)
    with pytest.raises(ABBException, match="Symbol not found"):
        client.get_rapid_variable("user/tNothing")


def test_the_controller_reads_a_write_as_rapid_not_as_python(
    abb_rws1_sim: AbbRwsSimulator,
) -> None:
    """The simulator reads a write with its own RAPID reader: the RAPID manual's example
    tooldata is taken, spaces and exponents included; what only Python's float would take
    (``1_000``, ``nan``) is refused (the connector's parser takes ``1_000``: a writer sharing
    it would pass a shared reader)."""
    from abb_robot_client.rws import RWS, ABBException

    tail = "[5,[23,0,75],[1,0,0,0],0,0,0]]"
    assert parse_tooldata(f"[TRUE,[[1_000,0,0],[1,0,0,0]],{tail}").position_mm[0] == 1000.0
    client = RWS(abb_rws1_sim.base_url, "Default User", "robotics")
    client.set_rapid_variable(
        "user/tTorch", f"[TRUE, [[97.5, 0, 2.2325E+02], [0.5, -0.5, 0.5, -0.5]], {tail}"
    )
    held = abb_rws1_sim.tool("T_ROB1/user/tTorch")
    assert (held.trans, held.rot) == ((97.5, 0.0, 223.25), (0.5, -0.5, 0.5, -0.5))
    for bad in ("[[1_000,0,0],[1,0,0,0]]", "[[nan,0,0],[1,0,0,0]]", "[[0,0,0],[1,0,0]]"):
        with pytest.raises(ABBException, match="Invalid value for tooldata"):
            client.set_rapid_variable("user/tTorch", f"[TRUE,{bad},{tail}")
    assert abb_rws1_sim.tool("T_ROB1/user/tTorch").trans == held.trans


@pytest.mark.filterwarnings("ignore::urllib3.exceptions.InsecureRequestWarning")
def test_rwswrap_reads_and_writes_the_rws2_simulator(abb_rws2_sim: AbbRwsSimulator) -> None:
    from rwswrap.RWS import RWS as RWS2

    abb_rws2_sim.set_tool("T_ROB1/user/tTorch", (0.0, 0.0, 150.0), (1.0, 0.0, 0.0, 0.0))
    client = RWS2(abb_rws2_sim.base_url, username="Default User", password="robotics")
    value = client.get_rapid_variable("tTorch", module="user")
    assert value == "[TRUE,[[0,0,150],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]]"
    written = "[TRUE,[[4,5,6],[0,0,0,1]],[1,[0,0,1],[1,0,0,0],0,0,0]]"
    assert client.set_rapid_variable("tTorch", written, module="user").status_code == 204
    assert abb_rws2_sim.tool("T_ROB1/user/tTorch").trans == (4.0, 5.0, 6.0)
    assert abb_rws2_sim.mastership_holder is None, "rwswrap released the mastership it took"


# --- where the robot stands (issue 39) ------------------------------------------------------

ROBTARGET = "/rw/motionsystem/mechunits/ROB_1/robtarget"
JOINTTARGET = "/rw/motionsystem/mechunits/ROB_1/jointtarget"


def _general_pose(seed: int) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """A flange somewhere in a robot's reach, any orientation, six joint angles."""
    tool = random_tool(seed, load=False)
    rng = np.random.default_rng(seed)
    position = tuple(float(v) for v in rng.uniform(-1500, 1500, 3))
    joints = tuple(float(v) for v in rng.uniform(-170, 170, 6))
    return position, tool.quaternion, joints


@pytest.mark.parametrize("version", [1, 2])
@pytest.mark.parametrize("seed", range(3))
def test_read_pose_is_the_robtarget_of_tool0_in_base_and_the_jointtarget(
    version: int, seed: int
) -> None:
    """The flange is read as tool0 in wobj0, Base coordinates: a non-zero active tool and an
    active work object off the base (what a program last moved by) change nothing."""
    position, quaternion, joints = _general_pose(seed)
    with AbbRwsSimulator(version, single_precision=False) as sim:
        sim.set_pose(position, quaternion, joints)  # type: ignore[arg-type]
        sim.set_tool("T_ROB1/user/tGripper", (10.0, -20.0, 180.0), (0.5, 0.5, 0.5, 0.5))
        sim.active_tool = "tGripper"
        sim.wobjs["wobjTable"] = ((800.0, -300.0, 200.0), (0.0, 0.0, 0.0, 1.0))
        sim.active_wobj = "wobjTable"
        with connect(abb_settings(sim)) as abb:
            assert isinstance(abb, AbbRwsConnector)
            reading = abb.read_pose()
        asked = [
            q
            for (_, path, _), q in zip(sim.requests, sim.queries, strict=True)
            if path == ROBTARGET
        ]
    assert_allclose(reading.flange.position_mm, position, atol=1e-6)
    assert angle_between_deg(reading.flange.quaternion, quaternion) < 1e-6
    assert reading.joints_deg is not None
    assert_allclose(reading.joints_deg, joints, atol=1e-6)
    assert reading.live_tool == LiveTool(None, None)
    json = {"json": "1"} if version == 1 else {}
    expected = {"tool": "tool0", "wobj": "wobj0", "coordinate": "Base", **json}
    assert asked, "the robtarget was read"
    assert all(query == expected for query in asked), asked  # RWS 1.0: Digest asks twice
    # the readings are the answers' values as the controller printed them
    assert float(reading.readings["robtarget.x"]) == position[0]
    assert reading.readings["robtarget.cf1"] == "0"
    assert reading.readings["robtarget.eax_a"] == "8.999999e+009"
    assert float(reading.readings["jointtarget.rax_6"]) == joints[5]
    assert "robtarget._type" not in reading.readings


def test_read_pose_keeps_the_printed_text_of_a_32_bit_controller(
    abb_rws2_sim: AbbRwsSimulator,
) -> None:
    """A num held as a 32-bit float is printed in its shortest form ("-0.1"), and read as
    that text says, not as the float32's exact value (-0.10000000149...)."""
    abb_rws2_sim.set_pose((1234.5, -0.1, 9.0), (0.5, -0.5, 0.5, 0.5), (0.1, 0, 0, 0, 90, 0))
    with connect(abb_settings(abb_rws2_sim)) as abb:
        reading = abb.read_pose()
    assert reading.readings["robtarget.y"] == "-0.1"
    assert reading.readings["robtarget.q2"] == "-0.5"
    assert reading.readings["jointtarget.rax_1"] == "0.1"
    assert reading.flange.position_mm == (1234.5, -0.1, 9.0)
    assert reading.joints_deg == (0.1, 0.0, 0.0, 0.0, 90.0, 0.0)
    assert reading.flange.quaternion == (0.5, -0.5, 0.5, 0.5)


def test_read_pose_refuses_what_is_not_a_pose(abb_rws1_sim: AbbRwsSimulator) -> None:
    abb_rws1_sim.set_pose((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0), (0, 0, 0, 0, float("nan"), 0))
    with connect(abb_settings(abb_rws1_sim)) as abb:
        with pytest.raises(ControllerProtocolError, match="jointtarget's rax_5 is 'nan'"):
            abb.read_pose()
        abb_rws1_sim.set_pose((1.0, 2.0, 3.0), (0.5, 0.0, 0.0, 0.0), (0, 0, 0, 0, 0, 0))
        with pytest.raises(ControllerProtocolError, match="not a unit quaternion"):
            abb.read_pose()


@pytest.mark.parametrize("where", [ROBTARGET, JOINTTARGET])
def test_a_pose_read_that_stalls_ends_within_the_timeout(sim: AbbRwsSimulator, where: str) -> None:
    """Both reads keep to one deadline: a controller silent at the second (the jointtarget)
    fails the read within timeout_s of its start, not timeout_s after the first answer."""
    sim.fault = go_silent("before", f"GET {where}")
    settings = abb_settings(sim, timeout_s=0.5)
    started = time.monotonic()
    # silent at the first request: it never answered (perhaps not RWS); at the second it stopped
    silent = where == ROBTARGET
    said = "accepted the TCP connection and sent nothing" if silent else "did not answer"
    with pytest.raises(ControllerUnreachable, match=said) as raised, connect(settings) as abb:
        abb.read_pose()
    elapsed = time.monotonic() - started
    assert isinstance(raised.value, ControllerSilent) is silent
    assert settings.timeout_s * 0.9 <= elapsed < settings.timeout_s + 1.0, elapsed


def test_abb_robot_client_reads_the_rws1_simulators_pose(abb_rws1_sim: AbbRwsSimulator) -> None:
    """abb-robot-client reads the jointtarget whole, and the robtarget's x, y, z, q1..q4 and
    cf1..cfx; it then looks for the external axes as ``eaxa``..``eaxf``, where the RWS
    manual's robtarget example (and its jointtarget, which the client reads) spells them
    ``eax_a``..``eax_f``: the simulator keeps to the manual, so the client's get_robtarget
    ends in a KeyError on ``eaxa`` after asking exactly what the connector asks."""
    from abb_robot_client.rws import RWS

    abb_rws1_sim.set_pose((600.0, 50.5, 432.25), (0.5, 0.5, -0.5, 0.5), (10, -20, 30, 0, 45, 90))
    client = RWS(abb_rws1_sim.base_url, "Default User", "robotics")
    joints = client.get_jointtarget()
    assert list(joints.robax) == [10.0, -20.0, 30.0, 0.0, 45.0, 90.0]
    with pytest.raises(KeyError, match="eaxa"):
        client.get_robtarget()
    assert abb_rws1_sim.queries[-1] == {
        "tool": "tool0",
        "wobj": "wobj0",
        "coordinate": "Base",
        "json": "1",
    }
