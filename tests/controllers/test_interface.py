"""The connector interface's data: ports, slot ranges, what each protocol needs, and how
settings never show the password."""

from __future__ import annotations

import re

import pytest

from app.controllers import (
    DEFAULT_PORTS,
    PROTOCOLS,
    SLOT_RANGES,
    TARGET_FIELD,
    ControllerSettings,
    ToolTarget,
    abb_symbol_problem,
    check_target,
    connect,
    split_abb_symbol,
    target_problem,
)
from app.controllers.abb_rws import AbbRwsConnector
from app.controllers.fanuc_rmi import FanucRmiConnector
from app.controllers.kuka_kvp import KukaKvpConnector
from tests.controllers.abb_sim import AbbRwsSimulator
from tests.controllers.fanuc_sim import FanucSimulator
from tests.controllers.fixtures import abb_settings, fanuc_settings, kuka_settings
from tests.controllers.kuka_sim import KukaSimulator


def test_every_protocol_has_a_port_and_a_target_field() -> None:
    assert PROTOCOLS == ("kuka_kvp", "fanuc_rmi", "abb_rws1", "abb_rws2")
    assert DEFAULT_PORTS == {"kuka_kvp": 7000, "fanuc_rmi": 16001, "abb_rws1": 80, "abb_rws2": 443}
    assert set(TARGET_FIELD) == set(PROTOCOLS)
    assert SLOT_RANGES == {"kuka_kvp": (1, 16), "fanuc_rmi": (1, 10)}


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
        ("ur_rtde", ToolTarget(slot=1), "unknown controller protocol 'ur_rtde'"),
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
    assert split_abb_symbol("T_ROB1/user/tTorch") == ("T_ROB1", "user", "tTorch")
    assert abb_symbol_problem("T_ROB1/user/tTorch") is None
    for bad in ("", "tTorch", "T_ROB1//tTorch", "T_ROB1/user/tTorch/x", "T ROB1/user/t"):
        with pytest.raises(ValueError, match="TASK/MODULE/SYMBOL"):
            split_abb_symbol(bad)


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
    with pytest.raises(ValueError, match="unknown controller protocol"):
        connect(ControllerSettings("ur_rtde", "127.0.0.1", 30004, None, None))  # type: ignore[arg-type]


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
