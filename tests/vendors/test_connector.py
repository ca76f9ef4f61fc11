"""The connector interface's data: ports, slot ranges, what each protocol needs, and how
settings never show the password."""

from __future__ import annotations

import re

import pytest

from app.vendors.abb.rws import AbbRwsConnector
from app.vendors.abb.symbol import split_symbol, symbol_problem
from app.vendors.connector import ControllerSettings, ToolTarget
from app.vendors.fanuc.rmi import FanucRmiConnector
from app.vendors.kuka.kvp import KukaKvpConnector
from app.vendors.registry import (
    DEFAULT_PORTS,
    SERVICE_PORTS,
    SLOT_RANGES,
    TARGET_FIELD,
    check_target,
    connect,
    describe_target,
    has_connector,
    target_problem,
)
from app.vendors.ur.rtde import UrRtdeConnector
from app.vendors.yaskawa.hses import YaskawaHsesConnector
from app.words import PROTOCOLS
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fanuc_sim import FanucSimulator
from tests.controllers.fixtures import (
    abb_settings,
    fanuc_settings,
    kuka_settings,
    ur_settings,
    yaskawa_settings,
)
from tests.controllers.kuka_sim import KukaSimulator
from tests.controllers.ur_sim import UrSimulator
from tests.controllers.yaskawa_sim import YaskawaSimulator


def test_every_protocol_has_a_port_and_a_target_field() -> None:
    """The protocols are the registry's (tests/vendors/test_registry.py holds their words and
    order). The ports and slot ranges below are pinned by hand on purpose: copied from the
    vendors' documents, an independent check of what each maker declares (a typo there moves
    where tcpcal connects or what it writes, and openapi.json's text follows the declaration,
    so only this copy would notice). A new maker adds its ports and slots here (README's
    "controller makers" row says so)."""
    assert DEFAULT_PORTS == {"kuka_kvp": 7000, "fanuc_rmi": 16001, "abb_rws1": 80, "abb_rws2": 443}
    # contract v1.3: a protocol of several services, each on its real port by default
    assert SERVICE_PORTS == {
        "techman": {"listen_node": 5890, "ethernet_slave": 5891},
        "yaskawa_hses": {"robot": 10040, "file": 10041},
        "ur_rtde": {"rtde": 30004, "secondary": 30002},
    }
    assert set(DEFAULT_PORTS) | set(SERVICE_PORTS) == set(PROTOCOLS)
    assert not set(DEFAULT_PORTS) & set(SERVICE_PORTS)
    assert set(TARGET_FIELD) == set(PROTOCOLS)
    assert SLOT_RANGES == {"kuka_kvp": (1, 16), "fanuc_rmi": (1, 10), "yaskawa_hses": (0, 63)}


@pytest.mark.parametrize(
    ("protocol", "target", "problem"),
    [
        ("kuka_kvp", ToolTarget(slot=16), None),
        ("kuka_kvp", ToolTarget(slot=17), "slot 17 is outside 1-16"),
        ("kuka_kvp", ToolTarget(slot=0), "slot 0 is outside 1-16"),
        ("kuka_kvp", ToolTarget(symbol="T_ROB1/user/t"), "set the tool's slot (1-16)"),
        ("fanuc_rmi", ToolTarget(slot=10), None),
        ("fanuc_rmi", ToolTarget(slot=11), "slot 11 is outside 1-10"),
        ("abb_rws1", ToolTarget(symbol="T_ROB1/user/tTorch"), None),
        ("abb_rws2", ToolTarget(slot=3), "set the tool's controller_symbol"),
        ("abb_rws2", ToolTarget(symbol="T_ROB1/tTorch"), 'is not "TASK/MODULE/SYMBOL"'),
        ("abb_rws1", ToolTarget(symbol="T_ROB1/user/1torch"), 'is not "TASK/MODULE/SYMBOL"'),
        ("abb_rws1", ToolTarget(symbol="T_ROB1/user/" + "t" * 33), "at most 32"),
        ("yaskawa_hses", ToolTarget(slot=0), None),
        ("yaskawa_hses", ToolTarget(slot=63), None),
        ("yaskawa_hses", ToolTarget(slot=64), "slot 64 is outside 0-63"),
        ("yaskawa_hses", ToolTarget(), "set the tool's slot (0-63)"),
        # named on the controller by values: any tool, with or without a slot
        ("ur_rtde", ToolTarget(slot=1), None),
        ("techman", ToolTarget(), None),
        ("kuka_rsi", ToolTarget(slot=1), "unknown controller protocol 'kuka_rsi'"),
    ],
)
def test_target_problem_names_what_to_set(
    protocol: str, target: ToolTarget, problem: str | None
) -> None:
    found = target_problem(protocol, target)
    if problem is None:
        assert found is None
        check_target(protocol, target)
    else:
        assert found is not None
        assert problem in found
        with pytest.raises(ValueError, match=re.escape(problem)):
            check_target(protocol, target)


def test_abb_symbols_split_into_task_module_symbol() -> None:
    assert split_symbol("T_ROB1/user/tTorch") == ("T_ROB1", "user", "tTorch")
    assert symbol_problem("T_ROB1/user/tTorch") is None
    for bad in ("", "tTorch", "T_ROB1//tTorch", "T_ROB1/user/tTorch/x", "T ROB1/user/t"):
        with pytest.raises(ValueError, match="TASK/MODULE/SYMBOL"):
            split_symbol(bad)


def test_settings_never_show_the_password() -> None:
    settings = ControllerSettings("abb_rws2", "10.0.0.5", 443, "admin", "hunter2-secret")
    assert "hunter2-secret" not in repr(settings)
    assert "hunter2-secret" not in str(settings)
    assert "password=<set>" in repr(settings)


def test_connect_picks_the_connector_of_the_protocol() -> None:
    with KukaSimulator() as kuka, connect(kuka_settings(kuka)) as connector:
        assert isinstance(connector, KukaKvpConnector)
        assert connector.describe(ToolTarget(slot=3)) == "$TOOL_DATA[3]"
    with FanucSimulator() as fanuc, connect(fanuc_settings(fanuc)) as connector:
        assert isinstance(connector, FanucRmiConnector)
        assert connector.describe(ToolTarget(slot=3)) == "UTOOL[3]"
    for version in (1, 2):
        with AbbRwsSimulator(version) as abb, connect(abb_settings(abb)) as connector:
            assert isinstance(connector, AbbRwsConnector)
            assert connector.protocol == f"abb_rws{version}"
    with YaskawaSimulator() as yaskawa, connect(yaskawa_settings(yaskawa)) as connector:
        assert isinstance(connector, YaskawaHsesConnector)
        assert connector.describe(ToolTarget(slot=3)) == "TOOL.CND tool 3"
    with UrSimulator() as ur, connect(ur_settings(ur)) as connector:
        assert isinstance(connector, UrRtdeConnector)
        assert connector.describe(ToolTarget()) == "tcp_offset"
    with pytest.raises(ValueError, match="unknown controller protocol"):
        connect(ControllerSettings("kuka_rsi", "127.0.0.1", 49152, None, None))  # type: ignore[arg-type]


def test_targets_of_the_new_protocols_are_named_as_their_controllers_name_them() -> None:
    assert describe_target("yaskawa_hses", ToolTarget(slot=5)) == "TOOL.CND tool 5"
    assert describe_target("ur_rtde", ToolTarget()) == "tcp_offset"
    assert describe_target("techman", ToolTarget(slot=2)) == "current TCP"


def test_connect_without_a_connector_for_a_known_protocol_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Until a protocol's connector is registered, connecting is a ValueError naming it
    (the service answers 501 /no-connector before it gets here). Every protocol has its
    connector now, so one is planted as a maker declares one not written yet."""
    from dataclasses import replace

    from app.vendors import registry

    protocol = PROTOCOLS[0]
    unwritten = replace(registry.WIRE_PROTOCOLS[protocol], connector=None)
    monkeypatch.setitem(registry.WIRE_PROTOCOLS, protocol, unwritten)
    assert not has_connector(protocol)
    settings = ControllerSettings(protocol, "127.0.0.1", 1, None, None)
    with pytest.raises(ValueError, match=f"no connector for controller protocol '{protocol}'"):
        connect(settings)


def test_a_simulator_switched_back_on_serves_on_its_port_again() -> None:
    with KukaSimulator() as kuka:
        port = kuka.port
        kuka.stop()
        kuka.start()
        assert kuka.port == port
        with connect(kuka_settings(kuka)) as connector:
            connector.read_tool(ToolTarget(slot=1))
    with FanucSimulator() as fanuc:
        ports = (fanuc.port, fanuc.session_port)
        fanuc.stop()
        fanuc.start()
        assert (fanuc.port, fanuc.session_port) == ports
        with connect(fanuc_settings(fanuc)) as connector:
            connector.read_tool(ToolTarget(slot=1))
    with AbbRwsSimulator(2) as abb:
        port = abb.port
        abb.stop()
        abb.start()
        assert abb.port == port
        with connect(abb_settings(abb)) as connector:
            connector.read_tool(ToolTarget(symbol="T_ROB1/user/tTorch"))
    with YaskawaSimulator() as yaskawa:
        ports = (yaskawa.robot_port, yaskawa.file_port)
        yaskawa.stop()
        yaskawa.start()
        assert (yaskawa.robot_port, yaskawa.file_port) == ports
        with connect(yaskawa_settings(yaskawa)) as connector:
            connector.read_tool(ToolTarget(slot=1))
    with UrSimulator() as ur:
        ports = (ur.rtde_port, ur.secondary_port)
        ur.stop()
        ur.start()
        assert (ur.rtde_port, ur.secondary_port) == ports
        with connect(ur_settings(ur)) as connector:
            connector.read_tool(ToolTarget())
