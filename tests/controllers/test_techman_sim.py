"""The Techman simulator against techmanpy (a client others wrote for TMflow's Listen Node
and Ethernet Slave) and against the packets the Listen Node manual prints."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Coroutine
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

import numpy as np
import pytest
import techmanpy
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from tests.controllers.simbase import go_silent
from tests.controllers.techman_sim import TechmanSimulator, exchange, packet

HOST = "127.0.0.1"
T = TypeVar("T")


def sct(sim: TechmanSimulator, timeout_s: float = 1.0) -> object:
    """techmanpy's Listen Node client, on the simulator's port (its ports are class
    attributes)."""
    client = type("Sct", (techmanpy.TMSCT_client,), {"PORT": sim.listen_node_port})
    return client(robot_ip=HOST, conn_timeout=timeout_s, suppress_warns=True)


def sta(sim: TechmanSimulator) -> object:
    client = type("Sta", (techmanpy.TMSTA_client,), {"PORT": sim.listen_node_port})
    return client(robot_ip=HOST, conn_timeout=1)


def svr(sim: TechmanSimulator) -> object:
    client = type("Svr", (techmanpy.TMSVR_client,), {"PORT": sim.ethernet_slave_port})
    return client(robot_ip=HOST, conn_timeout=1)


def run(coroutine: Coroutine[object, object, T], timeout_s: float = 5.0) -> T:
    """Run techmanpy's coroutine to its end in a thread of its own: in the full suite a module
    before this one on the same pytest worker (sync Playwright) can leave an event loop running
    in the worker's thread, where asyncio.run refuses to start."""
    with ThreadPoolExecutor(max_workers=1) as thread:
        return thread.submit(asyncio.run, asyncio.wait_for(coroutine, timeout_s)).result()


async def change_tcp(sim: TechmanSimulator, *args: object) -> None:
    async with sct(sim) as conn:  # type: ignore[attr-defined]
        await conn.set_tcp(*args)


async def read_items(sim: TechmanSimulator, *names: str) -> dict[str, object]:
    async with svr(sim) as conn:  # type: ignore[attr-defined]
        items: dict[str, object] = await conn.get_values(list(names))
        return items


def tm_matrix(values: list[float]) -> np.ndarray:
    """X Y Z RX RY RZ as a 4x4 matrix, the test's own reading of Techman's convention
    (R = Rz Ry Rx about fixed axes)."""
    m = np.eye(4)
    rz, ry, rx = (np.radians(v) for v in values[5:2:-1])
    m[:3, :3] = (
        Rotation.from_rotvec([0, 0, rz])
        * Rotation.from_rotvec([0, ry, 0])
        * Rotation.from_rotvec([rx, 0, 0])
    ).as_matrix()
    m[:3, 3] = values[:3]
    return m


@pytest.fixture
def sim(techman_sim: TechmanSimulator) -> TechmanSimulator:
    return techman_sim


def test_the_packets_are_the_manuals_examples() -> None:
    assert packet("TMSCT", "1,OK") == b"$TMSCT,4,1,OK,*5C\r\n"
    assert packet("TMSCT", "3,ERROR;1;2;3") == b"$TMSCT,13,3,ERROR;1;2;3,*3F\r\n"
    assert packet("TMSCT", "0,Listen1") == b"$TMSCT,9,0,Listen1,*4C\r\n"
    assert packet("TMSTA", "00,false,") == b"$TMSTA,9,00,false,,*37\r\n"
    assert packet("CPERR", "F1") == b"$CPERR,2,F1,*3F\r\n"


def test_techmanpy_changes_the_tcp_and_reads_it_with_the_poses(sim: TechmanSimulator) -> None:
    sim.jog_flange(417.5, -122.25, 610.0, 175.0, -3.5, 88.0)
    sim.set_joints(10.0, -20.0, 95.0, 5.0, 90.0, -45.0)
    tcp = [12.5, -3.25, 187.125, 10.0, -20.0, 30.0]
    run(change_tcp(sim, tcp, 1.75))
    items = run(
        read_items(
            sim,
            "TCP_Value",
            "TCP_Mass",
            "TCP_Name",
            "Coord_Robot_Flange",
            "Coord_Robot_Tool",
            "Joint_Angle",
        )
    )
    assert sim.scripts[-1][1] == "ChangeTCP(12.5,-3.25,187.125,10.0,-20.0,30.0,1.75)"
    assert_allclose(items["TCP_Value"], tcp, atol=1e-5)  # type: ignore[call-overload]
    assert items["TCP_Mass"] == pytest.approx(1.75)
    assert items["TCP_Name"] == ""
    flange = tm_matrix(items["Coord_Robot_Flange"])  # type: ignore[arg-type]
    assert_allclose(flange, tm_matrix([417.5, -122.25, 610.0, 175.0, -3.5, 88.0]), atol=1e-4)
    tool = tm_matrix(items["Coord_Robot_Tool"])  # type: ignore[arg-type]
    assert_allclose(tool, flange @ tm_matrix(tcp), atol=1e-4)
    assert items["Joint_Angle"] == [10.0, -20.0, 95.0, 5.0, 90.0, -45.0]


def test_the_inertia_overload_and_a_tcp_of_the_list(sim: TechmanSimulator) -> None:
    run(change_tcp(sim, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0], 2.0, [0.1, 0.2, 0.3, 4, 5, 6, 0, 0, 0]))
    name, held = sim.current_tcp()
    assert (name, held.values, held.mass) == ("", (1.0, 2.0, 3.0, 0.0, 0.0, 0.0), 2.0)
    assert_allclose(held.inertia, [0.1, 0.2, 0.3, 4, 5, 6, 0, 0, 0], atol=1e-7)
    sim.add_tcp("Gripper", (0.0, 0.0, 120.0, 0.0, 0.0, 45.0), mass=0.8)
    run(change_tcp(sim, "Gripper"))
    assert sim.scripts[-1][1] == 'ChangeTCP("Gripper")'
    items = run(read_items(sim, "TCP_Name", "TCP_Value", "TCP_Mass"))
    assert items == {
        "TCP_Name": "Gripper",
        "TCP_Value": [0.0, 0.0, 120.0, 0.0, 0.0, 45.0],
        "TCP_Mass": pytest.approx(0.8),
    }


def test_a_script_in_error_names_its_line_and_runs_nothing(sim: TechmanSimulator) -> None:
    with pytest.raises(techmanpy.TMSCTError, match="resulted in an error"):
        run(change_tcp(sim, "NoSuchTool"))
    [reply] = exchange(
        sim.listen_node_port,
        packet("TMSCT", '7,ChangeTCP(1,2,3,0,0,0)\r\nChangeTCP(1,2)\r\nPTP("JPP",0,0,0,0,0,0)'),
    )
    assert reply == packet("TMSCT", "7,ERROR;2;3")
    assert sim.current_tcp() == ("NOTOOL", sim.tcp_list["NOTOOL"])


def test_outside_the_listen_node_a_script_is_refused_with_cperr_f1(sim: TechmanSimulator) -> None:
    sim.leave_listen_node()
    with pytest.raises(techmanpy.TMProtocolError, match="Listen Node is not active"):
        run(change_tcp(sim, [0.0, 0.0, 100.0, 0.0, 0.0, 0.0]))
    assert sim.current_tcp()[1].values == (0.0,) * 6
    assert run(_listening(sim)) is False
    sim.enter_listen_node()
    assert run(_listening(sim)) is True


async def _listening(sim: TechmanSimulator) -> bool:
    async with sta(sim) as conn:  # type: ignore[attr-defined]
        active: bool = await conn.is_listen_node_active()
        return active


def test_script_exit_leaves_the_node(sim: TechmanSimulator) -> None:
    async def leave() -> None:
        async with sct(sim) as conn:  # type: ignore[attr-defined]
            await conn.exit_listen()

    run(leave())
    assert sim.in_listen_node is False
    assert exchange(sim.listen_node_port, packet("TMSCT", "1,QueueTag(1)")) == [
        b"$CPERR,2,F1,*3F\r\n"
    ]


def test_entering_the_node_tells_the_connected_client(sim: TechmanSimulator) -> None:
    import socket

    sim.leave_listen_node()
    with socket.create_connection((HOST, sim.listen_node_port), timeout=2) as sock:
        deadline = time.monotonic() + 2
        while sim._holder is None and time.monotonic() < deadline:
            time.sleep(0.01)
        sim.enter_listen_node()
        assert sock.recv(100) == b"$TMSCT,9,0,Listen1,*4C\r\n"


def test_no_project_running_no_listen_node_and_a_start_sets_the_projects_tcp(
    sim: TechmanSimulator,
) -> None:
    sim.add_tcp("Torch", (0.0, 5.0, 350.0, 0.0, 25.0, 0.0))
    sim.project_tcp = "Torch"
    run(change_tcp(sim, [0.0, 0.0, 100.0, 0.0, 0.0, 0.0]))
    sim.stop_project()
    with pytest.raises(techmanpy.TMConnectError):
        run(change_tcp(sim, [0.0, 0.0, 200.0, 0.0, 0.0, 0.0]))
    assert run(read_items(sim, "Project_Run", "TCP_Value")) == {
        "Project_Run": False,
        "TCP_Value": [0.0, 0.0, 100.0, 0.0, 0.0, 0.0],
    }
    sim.start_project()
    assert run(read_items(sim, "TCP_Name", "TCP_Value")) == {
        "TCP_Name": "Torch",
        "TCP_Value": [0.0, 5.0, 350.0, 0.0, 25.0, 0.0],
    }
    run(change_tcp(sim, [0.0, 0.0, 200.0, 0.0, 0.0, 0.0]))  # the node is back on its port
    assert sim.current_tcp()[1].values[2] == 200.0


def test_a_pendant_side_change_shows_in_the_data_table(sim: TechmanSimulator) -> None:
    run(change_tcp(sim, [0.0, 0.0, 100.0, 0.0, 0.0, 0.0], 1.0))
    sim.add_tcp("Probe", (1.0, 1.0, 90.0, 0.0, 0.0, 0.0), mass=0.2)
    sim.select_tcp("Probe")
    assert run(read_items(sim, "TCP_Name", "TCP_Value"))["TCP_Name"] == "Probe"
    sim.set_current_tcp((0.0, 0.0, 101.0, 0.0, 0.0, 0.0))
    assert run(read_items(sim, "TCP_Name", "TCP_Value", "TCP_Mass")) == {
        "TCP_Name": "",
        "TCP_Value": [0.0, 0.0, 101.0, 0.0, 0.0, 0.0],
        "TCP_Mass": 0.0,
    }


@pytest.mark.parametrize(("moment", "changed"), [("before", False), ("after", True)])
def test_silence_mid_script_and_the_controller_back(
    sim: TechmanSimulator, moment: str, changed: bool
) -> None:
    sim.fault = go_silent(moment, "ChangeTCP")  # type: ignore[arg-type]
    with pytest.raises(TimeoutError):
        run(change_tcp(sim, [0.0, 0.0, 150.0, 0.0, 0.0, 0.0]), timeout_s=1.0)
    assert (sim.current_tcp()[1].values[2] == 150.0) is changed
    with pytest.raises(TimeoutError):
        run(read_items(sim, "TCP_Value"), timeout_s=0.5)  # the Ethernet Slave is silent too
    sim.stalled = False
    run(change_tcp(sim, [0.0, 0.0, 160.0, 0.0, 0.0, 0.0]))
    assert run(read_items(sim, "TCP_Value"))["TCP_Value"] == [0.0, 0.0, 160.0, 0.0, 0.0, 0.0]


def test_a_session_left_open_blocks_the_next_until_it_closes(sim: TechmanSimulator) -> None:
    import socket

    left = socket.create_connection((HOST, sim.listen_node_port))
    try:
        deadline = time.monotonic() + 2
        while sim._holder is None and time.monotonic() < deadline:
            time.sleep(0.01)
        with pytest.raises(TimeoutError):
            run(change_tcp(sim, [0.0, 0.0, 150.0, 0.0, 0.0, 0.0]), timeout_s=1.0)
        assert sim.current_tcp()[1].values[2] == 0.0
    finally:
        left.close()
    run(change_tcp(sim, [0.0, 0.0, 150.0, 0.0, 0.0, 0.0]))
    assert sim.current_tcp()[1].values[2] == 150.0
    deadline = time.monotonic() + 2
    while sim.listen_node_clients() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert sim.listen_node_clients() == 0


def test_the_queue_runs_a_change_after_its_ok_and_a_tag_says_when(sim: TechmanSimulator) -> None:
    sim.queue_delay_s = 0.4

    async def change_and_tag() -> None:
        async with sct(sim) as conn:  # type: ignore[attr-defined]
            transaction = conn.start_transaction()
            transaction.set_tcp([0.0, 0.0, 77.0, 0.0, 0.0, 0.0])
            transaction.set_queue_tag(3)
            await transaction.submit()

    async def tag() -> bool:
        async with sta(sim) as conn:  # type: ignore[attr-defined]
            reached: bool = await conn.get_queue_tag_status(3)
            return reached

    run(change_and_tag())
    assert sim.scripts[-1][1] == "ChangeTCP(0.0,0.0,77.0,0.0,0.0,0.0)\r\nQueueTag(3,0)"
    assert run(tag()) is False
    assert run(read_items(sim, "TCP_Value"))["TCP_Value"][2] == 0.0  # type: ignore[index]
    time.sleep(0.45)
    assert run(tag()) is True
    assert run(read_items(sim, "TCP_Value"))["TCP_Value"][2] == 77.0  # type: ignore[index]


def test_ethernet_slave_refusals(sim: TechmanSimulator) -> None:
    with pytest.raises(techmanpy.TMSVRError, match=r"does not exist.*No_Such_Item"):
        run(read_items(sim, "TCP_Value", "No_Such_Item"))
    sim.data_table.discard("Coord_Robot_Flange")
    with pytest.raises(techmanpy.TMSVRError, match=r"does not exist.*Coord_Robot_Flange"):
        run(read_items(sim, "Coord_Robot_Flange"))

    async def write() -> None:
        async with svr(sim) as conn:  # type: ignore[attr-defined]
            await conn.set_value("TCP_Value", [0, 0, 10, 0, 0, 0])

    with pytest.raises(techmanpy.TMSVRError, match=r"read-only.*TCP_Value"):
        run(write())
    assert sim.current_tcp()[1].values == (0.0,) * 6


def test_the_data_table_is_broadcast_and_answers_are_matched_by_id(sim: TechmanSimulator) -> None:
    seen: list[dict[str, object]] = []

    async def listen() -> dict[str, object]:
        async with svr(sim) as conn:  # type: ignore[attr-defined]
            conn.add_broadcast_callback(seen.append)
            await asyncio.sleep(0.35)
            items: dict[str, object] = await conn.get_values(["TCP_Name"])
            return items

    assert run(listen()) == {"TCP_Name": "NOTOOL"}
    assert len(seen) >= 2
    assert seen[0]["TCP_Value"] == [0.0] * 6
    assert seen[0]["Project_Run"] is True


def test_json_reads_print_six_decimals_like_the_robot() -> None:
    with TechmanSimulator(broadcast_s=None) as quiet:
        quiet.jog_flange(-179.4, 343.78, 224.89, -158.37, -9.71, -122.43)
        [reply] = exchange(
            quiet.ethernet_slave_port, packet("TMSVR", '01,13,[{"Item":"Coord_Robot_Flange"}]')
        )
    text = reply.decode()
    assert text.startswith("$TMSVR,")
    assert ',01,13,[{"Item":"Coord_Robot_Flange","Value":[' in text
    values = text.split("[", 2)[2].split("]")[0].split(",")
    assert all(len(v.split(".")[1]) == 6 for v in values)
    assert [float(v) for v in values] == pytest.approx(
        [-179.4, 343.78, 224.89, -158.37, -9.71, -122.43], abs=1e-4
    )


@pytest.mark.parametrize(
    ("port", "data", "code"),
    [
        ("listen_node_port", b"$TMSCT,4,1,OK,*00\r\n", "02"),  # checksum
        ("listen_node_port", packet("TMSVR", "1,12,TCP_Value"), "03"),  # header
        ("listen_node_port", b"$TMSCT,99,1,QueueTag(1),*3E\r\n", "01"),  # length
        ("listen_node_port", packet("TMSTA", "07"), "04"),  # data
        ("ethernet_slave_port", packet("TMSCT", "1,QueueTag(1)"), "03"),
        ("ethernet_slave_port", packet("TMSVR", "nomode"), "04"),
    ],
)
def test_a_packet_that_cannot_be_read_earns_a_cperr(port: str, data: bytes, code: str) -> None:
    with TechmanSimulator(broadcast_s=None) as quiet:
        assert exchange(getattr(quiet, port), data) == [packet("CPERR", code)]


def test_a_moving_robot_moves_between_reads(sim: TechmanSimulator) -> None:
    sim.moving_per_read = 0.5
    first = run(read_items(sim, "Coord_Robot_Flange"))["Coord_Robot_Flange"]
    second = run(read_items(sim, "Coord_Robot_Flange"))["Coord_Robot_Flange"]
    assert second[0] - first[0] == pytest.approx(0.5, abs=1e-4)  # type: ignore[index]


# --- bases: ChangeBase through the Listen Node, Base_Value / Base_Name from the Slave ------


async def change_base(sim: TechmanSimulator, base: object) -> None:
    async with sct(sim) as conn:  # type: ignore[attr-defined]
        await conn.set_base(base)


def test_techmanpy_changes_the_base_and_reads_it_back(sim: TechmanSimulator) -> None:
    sim.add_base("Fixture", (100.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    sim.add_tcp("Gripper", (0.0, 0.0, 120.0, 0.0, 0.0, 45.0), mass=0.8)
    sim.select_tcp("Gripper")
    tcp_before = sim.current_tcp()
    base = [612.5, -240.25, 35.125, 0.5, -1.25, 89.75]
    run(change_base(sim, base))
    items = run(read_items(sim, "Base_Value", "Base_Name", "TCP_Value", "TCP_Name"))
    assert sim.scripts[-1][1] == "ChangeBase(612.5,-240.25,35.125,0.5,-1.25,89.75)"
    assert_allclose(items["Base_Value"], base, atol=1e-5)  # type: ignore[call-overload]
    assert items["Base_Name"] == ""
    assert sim.current_base() == ("", tuple(float(np.float32(v)) for v in base))
    # the base list and the TCP are untouched by a base change
    assert sim.base_list == {"RobotBase": (0.0,) * 6, "Fixture": (100.0, 0.0, 0.0, 0.0, 0.0, 0.0)}
    assert sim.current_tcp() == tcp_before
    assert items["TCP_Name"] == "Gripper"
    assert items["TCP_Value"] == [0.0, 0.0, 120.0, 0.0, 0.0, 45.0]


def test_a_base_of_the_list_by_name_and_the_poses_in_it(sim: TechmanSimulator) -> None:
    sim.jog_flange(417.5, -122.25, 610.0, 175.0, -3.5, 88.0)
    fixture = [300.0, 200.0, 50.0, 0.0, 0.0, 30.0]
    sim.add_base("Fixture", tuple(fixture))
    run(change_base(sim, "Fixture"))
    items = run(
        read_items(sim, "Base_Name", "Base_Value", "Coord_Robot_Flange", "Coord_Base_Flange")
    )
    assert sim.scripts[-1][1] == 'ChangeBase("Fixture")'
    assert items["Base_Name"] == "Fixture"
    assert items["Base_Value"] == fixture
    robot = tm_matrix(items["Coord_Robot_Flange"])  # type: ignore[arg-type]
    in_base = tm_matrix(items["Coord_Base_Flange"])  # type: ignore[arg-type]
    assert_allclose(tm_matrix(fixture) @ in_base, robot, atol=1e-3)


def test_a_base_not_in_the_list_or_not_six_numbers_runs_nothing(sim: TechmanSimulator) -> None:
    with pytest.raises(techmanpy.TMSCTError, match="resulted in an error"):
        run(change_base(sim, "NoSuchBase"))
    [reply] = exchange(
        sim.listen_node_port,
        packet("TMSCT", "8,ChangeBase(1,2,3,0,0,0)\r\nChangeBase(1,2,3)\r\nChangeBase({1,2})"),
    )
    assert reply == packet("TMSCT", "8,ERROR;2;3")
    assert sim.current_base() == ("RobotBase", (0.0,) * 6)


def test_a_project_start_sets_the_projects_base_again(sim: TechmanSimulator) -> None:
    sim.add_base("Table", (0.0, 500.0, 0.0, 0.0, 0.0, 0.0))
    sim.project_base = "Table"
    run(change_base(sim, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0]))
    assert sim.current_base() == ("", (1.0, 2.0, 3.0, 0.0, 0.0, 0.0))
    sim.start_project()
    assert run(read_items(sim, "Base_Name", "Base_Value")) == {
        "Base_Name": "Table",
        "Base_Value": [0.0, 500.0, 0.0, 0.0, 0.0, 0.0],
    }


def test_a_base_change_waits_in_the_motion_queue(sim: TechmanSimulator) -> None:
    sim.queue_delay_s = 0.4
    run(change_base(sim, [0.0, 0.0, 10.0, 0.0, 0.0, 0.0]))
    assert run(read_items(sim, "Base_Value"))["Base_Value"] == [0.0] * 6
    time.sleep(0.45)
    assert run(read_items(sim, "Base_Value"))["Base_Value"] == [0.0, 0.0, 10.0, 0.0, 0.0, 0.0]


@pytest.mark.parametrize(("moment", "changed"), [("before", False), ("after", True)])
def test_silence_around_a_base_change(sim: TechmanSimulator, moment: str, changed: bool) -> None:
    """Cut before the ChangeBase: no answer and the old base; cut after: no answer, the new."""
    sim.fault = go_silent(moment, "ChangeBase")  # type: ignore[arg-type]
    with pytest.raises(TimeoutError):
        run(change_base(sim, [0.0, 0.0, 250.0, 0.0, 0.0, 0.0]), timeout_s=1.0)
    assert (sim.current_base()[1][2] == 250.0) is changed
    with pytest.raises(TimeoutError):
        run(read_items(sim, "Base_Value"), timeout_s=0.5)  # the Ethernet Slave is silent too
    sim.stalled = False
    expected = [0.0, 0.0, 250.0 if changed else 0.0, 0.0, 0.0, 0.0]
    assert run(read_items(sim, "Base_Value"))["Base_Value"] == expected


def test_the_base_items_are_read_only(sim: TechmanSimulator) -> None:
    async def write() -> None:
        async with svr(sim) as conn:  # type: ignore[attr-defined]
            await conn.set_value("Base_Value", [1, 2, 3, 0, 0, 0])

    with pytest.raises(techmanpy.TMSVRError, match=r"read-only.*Base_Value"):
        run(write())
    assert sim.current_base() == ("RobotBase", (0.0,) * 6)
    sim.data_table.discard("Base_Name")
    with pytest.raises(techmanpy.TMSVRError, match=r"does not exist.*Base_Name"):
        run(read_items(sim, "Base_Name"))
