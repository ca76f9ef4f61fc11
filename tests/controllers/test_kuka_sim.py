"""The KUKA simulator's base table against py-openshowvar (a client others wrote for
KUKAVARPROXY, on PyPI): BASE_DATA[n], BASE_NAME[n,], BASE_TYPE[n], $BASE and $ACT_BASE."""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterator

import numpy as np
import pytest
from numpy.testing import assert_allclose
from py_openshowvar import openshowvar
from scipy.spatial.transform import Rotation

from tests.controllers.kuka_sim import BASES, KukaSimulator
from tests.controllers.simbase import go_silent

BASE = "{X 1250.5,Y -310.25,Z 80.125,A 90.0,B 0.0,C 180.0}"
BASE_PRINTED = b"{FRAME: X 1250.5, Y -310.25, Z 80.125, A 90.0, B 0.0, C 180.0}"


@contextlib.contextmanager
def kvp(sim: KukaSimulator, timeout_s: float = 2.0) -> Iterator[openshowvar]:
    client = openshowvar(sim.host, sim.port)
    client.sock.settimeout(timeout_s)
    try:
        yield client
    finally:
        client.close()


def seeded(sim: KukaSimulator) -> tuple[dict[int, tuple[float, ...]], dict[int, tuple[float, ...]]]:
    """Every base and tool set to something of its own: (bases, tools) as held."""
    for n in BASES:
        sim.set_base_data(n, 100.0 * n, -5.0 * n, 3.0, float(n), 0.0, 0.0)
    for slot in range(1, 17):
        sim.set_tool(slot, 1.0, 2.0, 100.0 + slot, 0.0, 90.0, 0.0)
    return {n: sim.base_data(n) for n in BASES}, {s: sim.tool(s) for s in range(1, 17)}


def test_py_openshowvar_writes_and_reads_a_base_touching_nothing_else(
    kuka_sim: KukaSimulator,
) -> None:
    bases, tools = seeded(kuka_sim)
    with kvp(kuka_sim) as client:
        assert client.write("BASE_DATA[7]", BASE, debug=False) == BASE.encode()
        assert client.read("BASE_DATA[7]", debug=False) == BASE_PRINTED
        assert client.write("BASE_NAME[7,]", '"fixture_7"', debug=False) == b'"fixture_7"'
        assert client.read("BASE_NAME[7,]", debug=False) == b'"fixture_7"'
        assert client.write("BASE_TYPE[7]", "#BASE", debug=False) == b"#BASE"
        assert client.read("BASE_TYPE[7]", debug=False) == b"#BASE"
    assert kuka_sim.bases[7] == {
        "X": 1250.5,
        "Y": -310.25,
        "Z": 80.125,
        "A": 90.0,
        "B": 0.0,
        "C": 180.0,
    }
    assert {n: kuka_sim.base_data(n) for n in BASES if n != 7} == {
        n: v for n, v in bases.items() if n != 7
    }
    assert {s: kuka_sim.tool(s) for s in range(1, 17)} == tools
    assert [n for n, name in kuka_sim.base_names.items() if name] == [7]
    assert [n for n, kind in kuka_sim.base_types.items() if kind != "#NONE"] == [7]


def test_a_write_naming_some_members_keeps_the_others(kuka_sim: KukaSimulator) -> None:
    kuka_sim.set_base_data(3, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    with kvp(kuka_sim) as client:
        client.write("BASE_DATA[3]", "{FRAME: Z -3.25E+02}", debug=False)
    assert kuka_sim.base_data(3) == (1.0, 2.0, -325.0, 4.0, 5.0, 6.0)


@pytest.mark.parametrize(
    ("variable", "value"),
    [
        ("BASE_DATA[0]", BASE),
        ("BASE_DATA[33]", BASE),
        ("BASE_DATA[2]", "{X 1.0, Q 2.0}"),  # a member a FRAME has not
        ("BASE_DATA[2]", "{X nan}"),
        ("BASE_NAME[2,]", '"' + "n" * 25 + '"'),  # CHAR[24]
        ("BASE_NAME[2,]", "fixture"),  # not a string literal
        ("BASE_TYPE[2]", "#WORLD"),
    ],
)
def test_what_the_krc_refuses_is_not_written(
    kuka_sim: KukaSimulator, variable: str, value: str
) -> None:
    bases, tools = seeded(kuka_sim)
    with kvp(kuka_sim) as client:
        # py-openshowvar returns None for a reply whose status byte is not 1
        assert client.write(variable, value, debug=False) is None
    assert {n: kuka_sim.base_data(n) for n in BASES} == bases
    assert kuka_sim.base_names[2] == ""
    assert kuka_sim.base_types[2] == "#NONE"
    assert {s: kuka_sim.tool(s) for s in range(1, 17)} == tools


def test_a_base_number_outside_1_to_32_reads_empty(kuka_sim: KukaSimulator) -> None:
    with kvp(kuka_sim) as client:
        assert client.read("BASE_DATA[33]", debug=False) == b""
        assert client.read("BASE_NAME[0,]", debug=False) == b""
        assert client.read("BASE_DATA[32]", debug=False).startswith(b"{FRAME: X 0.0")


def test_act_base_and_base_follow_the_selection_and_pos_act_is_in_it(
    kuka_sim: KukaSimulator,
) -> None:
    kuka_sim.jog_flange(1200.0, 100.0, 900.0, 0.0, 30.0, 0.0)
    kuka_sim.set_base_data(5, 1000.0, 0.0, 500.0, 90.0, 0.0, 0.0)
    with kvp(kuka_sim) as client:
        assert client.read("$ACT_BASE", debug=False) == b"-1"
        kuka_sim.select_base(5)
        assert client.read("$ACT_BASE", debug=False) == b"5"
        assert client.read("$BASE", debug=False) == client.read("BASE_DATA[5]", debug=False)
        pos = client.read("$POS_ACT", debug=False).decode()
        # a pendant edit of the selected base is the $BASE the robot moves in
        client.write("BASE_DATA[5]", "{X 1100.0}", debug=False)
        assert client.read("$BASE", debug=False).startswith(b"{FRAME: X 1100.0, Y 0.0, Z 500.0")
    members = dict(part.split(" ", 1) for part in pos.strip("{}").split(": ", 1)[1].split(", "))
    # the test's own: inverse(BASE_DATA[5]) * flange, A B C as Rz Ry Rx
    base = np.eye(4)
    base[:3, :3] = Rotation.from_euler("ZYX", (90, 0, 0), degrees=True).as_matrix()
    base[:3, 3] = (1000.0, 0.0, 500.0)
    flange = np.eye(4)
    flange[:3, :3] = Rotation.from_euler("ZYX", (0, 30, 0), degrees=True).as_matrix()
    flange[:3, 3] = (1200.0, 100.0, 900.0)
    tcp = np.linalg.inv(base) @ flange
    assert_allclose([float(members[k]) for k in "XYZ"], tcp[:3, 3], atol=1e-3)


@pytest.mark.parametrize(("moment", "new"), [("before", False), ("after", True)])
def test_silence_around_a_base_write(kuka_sim: KukaSimulator, moment: str, new: bool) -> None:
    """Cut before the write: no answer and the old base; cut after: no answer, the new."""
    bases, _ = seeded(kuka_sim)
    kuka_sim.fault = go_silent(moment, "write BASE_DATA[9]")  # type: ignore[arg-type]
    with kvp(kuka_sim, timeout_s=0.3) as client, pytest.raises(socket.timeout):
        client.write("BASE_DATA[9]", BASE, debug=False)
    assert kuka_sim.stalled
    expected = (1250.5, -310.25, 80.125, 90.0, 0.0, 180.0) if new else bases[9]
    assert kuka_sim.base_data(9) == expected
    kuka_sim.stalled = False
    with kvp(kuka_sim) as client:
        text = client.read("BASE_DATA[9]", debug=False)
    assert (text == BASE_PRINTED) is new
