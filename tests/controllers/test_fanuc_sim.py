"""The FANUC simulator's user frames against fanuc-rmi (a client others wrote for RMI, on
PyPI) and against the packets FANUC B-84184EN/03 prints (2.3.6, 2.3.8, 2.3.9, 2.3.17)."""

from __future__ import annotations

import contextlib
import io
import json
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from fanuc_rmi import RobotClient

from tests.controllers.fanuc_sim import (
    COMMAND_FAIL,
    FRAME_KEYS,
    INVALID_GROUP,
    INVALID_POSITION_DATA,
    INVALID_UFRAME,
    INVALID_UTOOL,
    UFRAMES,
    FanucSimulator,
)
from tests.controllers.simbase import go_silent

FRAME = {"X": 1250.5, "Y": -310.25, "Z": 80.125, "W": 179.5, "P": -2.25, "R": 91.75}
OTHER = (400.0, 500.0, 600.0, 10.0, 20.0, 30.0)
TOOL = (0.0, 0.0, 150.0, 90.0, 0.0, 0.0)


@contextlib.contextmanager
def rmi(sim: FanucSimulator, *, timeout_s: float = 2.0) -> Iterator[RobotClient]:
    """fanuc-rmi's RobotClient on `sim`'s session, connected (it reads the session port from
    "Port", not the manual's PortNumber: test_rmi.py; it is told the port). Its prints of
    every packet are swallowed."""
    client = RobotClient(
        host=sim.host,
        startup_port=sim.port,
        main_port=sim.session_port,
        attempts=1,
        startup_pause=0.0,
        socket_timeout=timeout_s,
        reader_timeout=timeout_s,
    )
    with contextlib.redirect_stdout(io.StringIO()):
        client.connect()
        try:
            yield client
        finally:
            if client.client_socket is not None:
                client.client_socket.close()


def raw(sim: FanucSimulator, *packets: dict[str, object]) -> list[dict[str, object]]:
    """Each packet sent on a fresh session by hand, as the manual prints it; the answers
    (once the session before has ended: one RMI client at a time)."""
    deadline = time.monotonic() + 2
    while sim.session_open and time.monotonic() < deadline:
        time.sleep(0.01)
    with socket.create_connection((sim.host, sim.port), timeout=2) as first:
        first.sendall(b'{"Communication": "FRC_Connect"}\r\n')
        port = json.loads(_line(first))["PortNumber"]
    answers = []
    with socket.create_connection((sim.host, port), timeout=2) as session:
        for packet in packets:
            session.sendall(json.dumps(packet).encode("ascii") + b"\r\n")
            answers.append(json.loads(_line(session)))
    return answers


def _line(sock: socket.socket) -> bytes:
    data = b""
    while not data.endswith(b"\r\n"):
        chunk = sock.recv(4096)
        assert chunk, "the controller closed the connection without answering"
        data += chunk
    return data


def seeded(sim: FanucSimulator) -> dict[int, tuple[float, ...]]:
    """Every user frame set to something of its own, UTOOL 4 to TOOL: the frames held."""
    for number in UFRAMES:
        sim.set_uframe(number, *(v + number for v in OTHER))
    sim.set_tool(4, *TOOL)
    return {number: sim.uframe(number) for number in UFRAMES}


def test_fanuc_rmi_writes_and_reads_a_user_frame_touching_nothing_else() -> None:
    with FanucSimulator() as sim:
        before = seeded(sim)
        tools_before = {slot: sim.tool(slot) for slot in sim.tools}
        with rmi(sim) as client:
            answer = client.write_uframe_data(3, FRAME)
            back = client.read_uframe_data(3)
        written = next(p for p in sim.packets if p.get("Command") == "FRC_WriteUFrameData")
    assert answer == {"Command": "FRC_WriteUFrameData", "ErrorID": 0, "Group": 1}
    # fanuc-rmi sends the manual's packet without the optional Group (group 1)
    assert written == {"Command": "FRC_WriteUFrameData", "FrameNumber": 3, "Frame": FRAME}
    assert sim.uframes[3] == FRAME  # each value exact in a 32-bit REAL
    assert back == FRAME
    assert {n: sim.uframe(n) for n in UFRAMES if n != 3} == {
        n: v for n, v in before.items() if n != 3
    }
    assert {slot: sim.tool(slot) for slot in sim.tools} == tools_before
    assert sim.tool(4) == TOOL


def test_a_frame_is_held_in_32_bit_reals() -> None:
    with FanucSimulator() as sim, rmi(sim) as client:
        client.write_uframe_data(9, dict.fromkeys(FRAME_KEYS, 0.1))
        back = client.read_uframe_data(9)
    assert back == dict.fromkeys(FRAME_KEYS, float(np.float32(0.1)))
    assert back["X"] != 0.1


@pytest.mark.parametrize("number", [0, 10, -1, 255])
def test_a_frame_number_outside_1_to_9_answers_rmit_003(number: int) -> None:
    with FanucSimulator() as sim:
        before = seeded(sim)
        with rmi(sim) as client:
            answer = client.write_uframe_data(number, FRAME)
        (read,) = raw(sim, {"Command": "FRC_ReadUFrameData", "FrameNumber": number})
    assert answer["ErrorID"] == INVALID_UFRAME == 2556931
    assert read["ErrorID"] == INVALID_UFRAME
    assert {n: sim.uframe(n) for n in UFRAMES} == before


def test_another_group_or_a_short_frame_is_refused_and_nothing_written() -> None:
    with FanucSimulator() as sim:
        before = seeded(sim)
        other_group, short, not_finite = raw(
            sim,
            {"Command": "FRC_WriteUFrameData", "FrameNumber": 2, "Frame": FRAME, "Group": 2},
            {"Command": "FRC_WriteUFrameData", "FrameNumber": 2, "Frame": {"X": 1.0}},
            {
                "Command": "FRC_WriteUFrameData",
                "FrameNumber": 2,
                "Frame": FRAME | {"Z": float("nan")},
            },
        )
    assert other_group == {"Command": "FRC_WriteUFrameData", "ErrorID": INVALID_GROUP, "Group": 2}
    assert short["ErrorID"] == not_finite["ErrorID"] == INVALID_POSITION_DATA
    assert {n: sim.uframe(n) for n in UFRAMES} == before


def test_a_write_while_the_robot_moves_is_refused_and_the_frame_kept() -> None:
    """2.3.9: "The Remote Motion Interface rejects this packet if the robot is in motion"."""
    with FanucSimulator() as sim:
        before = seeded(sim)
        sim.in_motion = True
        with rmi(sim) as client:
            refused = client.write_uframe_data(5, FRAME)
            sim.in_motion = False
            accepted = client.write_uframe_data(5, FRAME)
    assert refused["ErrorID"] == COMMAND_FAIL == 2556942
    assert accepted["ErrorID"] == 0
    assert sim.uframes[5] == FRAME
    assert {n: sim.uframe(n) for n in UFRAMES if n != 5} == {
        n: v for n, v in before.items() if n != 5
    }


def test_fanuc_rmi_reads_and_sets_the_active_frame_and_tool_numbers() -> None:
    with FanucSimulator() as sim:
        sim.select(uframe=3, utool=4)
        with rmi(sim) as client:
            first = client.get_uframe_utool()
            client.set_uframe_utool(uframe=7, utool=2)
            second = client.get_uframe_utool()
        refused = raw(
            sim,
            {"Command": "FRC_SetUFrameUTool", "UFrameNumber": 10, "UToolNumber": 1},
            {"Command": "FRC_SetUFrameUTool", "UFrameNumber": 1, "UToolNumber": 11},
            {"Command": "FRC_GetUFrameUTool", "Group": 3},
            {"Command": "FRC_GetUFrameUTool"},
        )
    assert first == {"UFrameNumber": 3, "UToolNumber": 4}
    assert second == {"UFrameNumber": 7, "UToolNumber": 2}
    assert [a["ErrorID"] for a in refused] == [INVALID_UFRAME, INVALID_UTOOL, INVALID_GROUP, 0]
    assert refused[3] == {
        "Command": "FRC_GetUFrameUTool",
        "ErrorID": 0,
        "UFrameNumber": 7,
        "UToolNumber": 2,
        "Group": 1,
    }


def test_the_active_user_frame_is_the_one_the_pose_is_read_in(tmp_path: Path) -> None:
    """A frame written over RMI moves the TCP read in it (2.3.14: Position is in UFRAME m)."""
    with FanucSimulator(single_precision=False) as sim:
        sim.jog_flange(1200.0, 100.0, 900.0, 180.0, 0.0, 0.0)
        sim.select(uframe=2, utool=0)
        with rmi(sim) as client:
            client.write_uframe_data(2, {"X": 1000.0, "Y": 0, "Z": 500.0, "W": 0, "P": 0, "R": 0})
            read = client.read_cartesian_coordinates(output_path=str(tmp_path / "pose.jsonl"))
    position = read["Position"]
    assert [position[k] for k in ("X", "Y", "Z")] == pytest.approx([200.0, 100.0, 400.0])


@pytest.mark.parametrize(("moment", "held"), [("before", "old"), ("after", "new")])
def test_silence_around_a_frame_write_leaves_the_old_frame_or_holds_the_new(
    moment: str, held: str
) -> None:
    """Cut before the write: no answer and the old frame; cut after: no answer, the new."""
    with FanucSimulator() as sim:
        before = seeded(sim)
        sim.fault = go_silent(moment, "FRC_WriteUFrameData")  # type: ignore[arg-type]
        with rmi(sim, timeout_s=0.3) as client, pytest.raises(TimeoutError):
            client.write_uframe_data(6, FRAME)
        assert sim.stalled
        expected = before | {6: tuple(FRAME[k] for k in FRAME_KEYS)} if held == "new" else before
        assert {n: sim.uframe(n) for n in UFRAMES} == expected
        sim.stalled = False  # the controller back: the next session reads what it holds
        with rmi(sim) as client:
            assert client.read_uframe_data(6) == dict(zip(FRAME_KEYS, expected[6], strict=True))


def test_a_session_left_behind_does_not_stop_a_frame_write() -> None:
    """A session that initialized and died holds RMI_MOVE (2.3.1 NOTE): a frame write needs
    only a connection (2.3, page 9) and is answered."""
    with FanucSimulator() as sim:
        with rmi(sim) as client:
            assert client.client_socket is not None
            client.client_socket.sendall(b'{"Command": "FRC_Initialize"}\r\n')
            assert client.reader is not None
            assert client.reader.read_json()["ErrorID"] == 0
        # closed without FRC_Abort or FRC_Disconnect: RMI_MOVE stays
        (initialize, write) = raw(
            sim,
            {"Command": "FRC_Initialize"},
            {"Command": "FRC_WriteUFrameData", "FrameNumber": 1, "Frame": FRAME},
        )
    assert sim.rmi_move_held
    assert initialize["ErrorID"] == 7015
    assert write["ErrorID"] == 0
    assert sim.uframes[1] == FRAME
