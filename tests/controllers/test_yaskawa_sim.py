"""The HSES simulator against yrcom (a client others wrote from the HSES manuals): status and
position reads on the robot port, file list, save and load on the file port, and the faults
the connector must survive (a refused load, silence mid-conversation, a transfer left
behind). Where yrcom reads the answer's status bytes at other offsets than the manual, the
raw answer is checked byte by byte too (tests/controllers/yaskawa_sim.py says why)."""

from __future__ import annotations

import socket
import struct
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation
from yrcom import HsesClient, HsesError, HsesFileClient, PositionVar

from tests.controllers.simbase import go_silent
from tests.controllers.yaskawa_sim import (
    CONDITION_FILE_RECORD,
    FILE_IN_USE,
    INCORRECT_MODE,
    INCORRECT_NUMBER_OF_DATA,
    LAST_BLOCK,
    REMOTE_OFF,
    TOOLS,
    YaskawaSimulator,
    parse_tool_cnd,
    print_tool_cnd,
)

TIMEOUT_S = 1.0


@pytest.fixture
def sim(yaskawa_sim: YaskawaSimulator) -> YaskawaSimulator:
    return yaskawa_sim


def robot_client(sim: YaskawaSimulator) -> HsesClient:
    return HsesClient(sim.host, sim.robot_port, timeout=TIMEOUT_S)


def file_client(sim: YaskawaSimulator) -> HsesFileClient:
    return HsesFileClient(sim.host, sim.file_port, timeout=TIMEOUT_S)


def request(
    division: int,
    service: int,
    data: bytes = b"",
    *,
    command: int = 0,
    instance: int = 0,
    ack: int = 0,
    block: int = 0,
    request_id: int = 7,
) -> bytes:
    """A request as the manual's 3.1 lays it out (written here, not taken from a client)."""
    header = struct.pack(
        "<4sHHBBBBI8s", b"YERC", 0x20, len(data), 3, division, ack, request_id, block, b"99999999"
    )
    return header + struct.pack("<HHBBH", command, instance, 0, service, 0) + data


def exchange(port: int, packet: bytes) -> bytes:
    """Send `packet` to 127.0.0.1:`port` and return the answer."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(TIMEOUT_S)
        sock.sendto(packet, ("127.0.0.1", port))
        return sock.recv(4096)


def status_bytes(reply: bytes) -> tuple[int, int, int, int]:
    """(service, status, added status size, added status) of an answer, at the manual's offsets."""
    service, status, size, _, added, _ = struct.unpack_from("<BBBBHH", reply, 24)
    return service, status, size, added


def place_tool_and_flange(sim: YaskawaSimulator) -> np.ndarray:
    sim.set_tool(3, (12.5, -4.25, 215.25), (10.0, -30.0, 45.0), name="TORCH")
    sim.select_tool(3)
    flange = np.eye(4)
    flange[:3, :3] = Rotation.from_euler("xyz", [170.0, 5.0, -20.0], degrees=True).as_matrix()
    flange[:3, 3] = (812.4, -120.7, 433.9)
    sim.set_flange(flange)
    expected: np.ndarray = flange @ sim.tool_frame(3)
    return expected


# --- robot control (UDP 10040) --------------------------------------------------------------


def test_yrcom_reads_the_status_bits(sim: YaskawaSimulator) -> None:
    with robot_client(sim) as client:
        play = client.read_status()
        sim.mode, sim.servo_on = "teach", False
        teach = client.read_status()
    assert (play["play"], play["teach"], play["cmd_remote"], play["servo_on"]) == (
        True,
        False,
        True,
        True,
    )
    assert (teach["play"], teach["teach"], teach["cmd_remote"], teach["servo_on"]) == (
        False,
        True,
        False,
        False,
    )


def test_yrcom_reads_the_tcp_in_the_base_frame_with_the_tool_number(
    sim: YaskawaSimulator,
) -> None:
    tcp = place_tool_and_flange(sim)
    with robot_client(sim) as client:
        read = client.read_position(101)
        # yrcom decodes no tool number: the record as PositionVar (13 integers, 3.3.6)
        record = PositionVar.from_bytes(client._tx(0x75, 101, 0, 0x01).data)
    assert_allclose([read[f"pos_{k}"] for k in "XYZ"], tcp[:3, 3], atol=0.0005)
    rxyz = [read[f"pos_{k}"] for k in ("Rx", "Ry", "Rz")]
    angle = Rotation.from_euler("xyz", rxyz, degrees=True).inv() * Rotation.from_matrix(tcp[:3, :3])
    assert np.degrees(angle.magnitude()) < 1e-4
    assert (record.data_type, record.tool_no, record.user_coord_no) == (16, 3, 0)
    assert record.axes[:3] == [round(v * 1000) for v in tcp[:3, 3]], "µm"


def test_one_attribute_of_the_position_and_a_missing_robot(sim: YaskawaSimulator) -> None:
    sim.select_tool(12)
    reply = exchange(sim.robot_port, request(1, 0x0E, command=0x75, instance=101))
    assert status_bytes(reply)[1] == 0x09, "attribute 0 with Get_Attribute_Single: no element"
    single = request(1, 0x0E, command=0x75, instance=101)
    single = single[:28] + bytes([3]) + single[29:]  # attribute 3: the tool number
    reply = exchange(sim.robot_port, single)
    assert status_bytes(reply) == (0x8E, 0, 0, 0)
    assert struct.unpack_from("<i", reply, 32)[0] == 12
    # R2 is not on this controller: status 0x28 and no added status, which yrcom, reading the
    # added status size (0) as the status, takes for success with no data.
    reply = exchange(sim.robot_port, request(1, 0x01, command=0x75, instance=102))
    assert status_bytes(reply) == (0x81, 0x28, 0, 0)
    with robot_client(sim) as client:
        assert client.read_position(102) == {}


def test_an_unknown_command_and_a_wrong_header(sim: YaskawaSimulator) -> None:
    assert status_bytes(exchange(sim.robot_port, request(1, 0x01, command=0x99)))[1] == 0x08
    bad = b"XERC" + request(1, 0x01, command=0x72, instance=1)[4:]
    assert status_bytes(exchange(sim.robot_port, bad))[1:] == (0x1F, 1, 0xE4A6)
    wrong_port = request(2, 0x16, b"TOOL.CND")
    assert status_bytes(exchange(sim.robot_port, wrong_port))[1:] == (0x1F, 1, 0xE4A3)


def test_a_status_answer_is_laid_out_as_the_manuals_example(sim: YaskawaSimulator) -> None:
    """3.2.1: the answer to a status read has block 0x8000_0000, service 0x81, status 0."""
    reply = exchange(sim.robot_port, request(1, 0x01, command=0x72, instance=1, request_id=42))
    magic, size, data_size, reserve, division, ack, rid, block, reserve_2 = struct.unpack_from(
        "<4sHHBBBBI8s", reply
    )
    assert (magic, size, data_size, reserve, division, ack, rid) == (b"YERC", 32, 8, 3, 1, 1, 42)
    assert (block, reserve_2) == (LAST_BLOCK, b"99999999")
    assert status_bytes(reply) == (0x81, 0, 0, 0)


# --- file control (UDP 10041) ---------------------------------------------------------------


def test_yrcom_lists_and_saves_tool_cnd_in_blocks(sim: YaskawaSimulator) -> None:
    place_tool_and_flange(sim)
    with file_client(sim) as client:
        names = client.list_files("*.CND")
        saved = client.read_file("TOOL.CND")
    assert "TOOL.CND" in names
    assert saved == sim.tool_cnd()
    assert len(saved) > 10 * 479, "many 479-byte blocks, each acknowledged"
    tools = parse_tool_cnd(saved.decode("ascii"))
    assert sorted(tools) == list(TOOLS)
    assert tools[3].name == "TORCH"
    assert tools[3].pose == (12500, -4250, 215250, 100000, -300000, 450000)
    assert sim.tool_block(3).startswith(b"//TOOL 3\r\n///CRC 381761669\r\n///NAME TORCH\r\n")
    assert b"12.500,-4.250,215.250,10.0000,-30.0000,45.0000\r\n" in sim.tool_block(3)


def test_yrcom_loads_one_changed_block_and_every_other_byte_stays(sim: YaskawaSimulator) -> None:
    sim.set_tool(9, (1.0, 2.0, 3.0), (0.0, 0.0, 90.0), name="GRIPPER", mass_kg=2.5)
    with file_client(sim) as client:
        before = client.read_file("TOOL.CND")
        old_block = sim.tool_block(5)
        new_block = old_block.replace(
            b"0.000,0.000,0.000,0.0000,0.0000,0.0000", b"-1.5,20.25,300.125,0.0,-90.0,180.0"
        ).replace(b"///CRC 381761669\r\n", b"")  # a block without its CRC keeps the controller's
        client.write_file("TOOL.CND", before.replace(old_block, new_block))
        after = client.read_file("TOOL.CND")
    assert sim.loads_applied == 1
    assert sim.tool(5) == ((-1.5, 20.25, 300.125), (0.0, -90.0, 180.0))
    assert after.replace(sim.tool_block(5), old_block) == before
    assert b"-1.500,20.250,300.125,0.0000,-90.0000,180.0000" in sim.tool_block(5)
    assert sim.tool_block(5).startswith(b"//TOOL 5\r\n///CRC 381761669\r\n")


def test_a_dx200_file_with_its_own_last_lines_round_trips() -> None:
    """A block as a DX200 backup writes it (no ///CRC, a last line of its own) prints back as
    it was, and a YRC1000 prints it with the CRC it keeps."""
    block_0 = (
        "//TOOL 0\n///NAME STANDARD TOOL\n0.000,0.000,0.000,0.0000,90.0000,0.0000\n"
        "-16.507,-21.039,-136.477\n104.011\n0.000,0.000,0.000\n0.000,0,3\n"
    )
    others = "".join(
        f"//TOOL {n}\n///NAME\n0.000,0.000,0.000,0.0000,0.0000,0.0000\n0.000,0.000,0.000\n"
        "0.000\n0.000,0.000,0.000\n0.000,0,1\n"
        for n in range(1, 64)
    )
    tools = parse_tool_cnd(block_0 + others)
    assert print_tool_cnd(tools, "DX200") == (block_0 + others).replace("\n", "\r\n").encode()
    assert tools[0].mass == 104011
    assert tools[0].cog == (-16507, -21039, -136477)
    assert print_tool_cnd(tools, "YRC1000").startswith(b"//TOOL 0\r\n///CRC 381761669\r\n")


@pytest.mark.parametrize(
    ("controller", "added"),
    [
        ({"mode": "teach"}, INCORRECT_MODE),
        ({"remote": False}, REMOTE_OFF),
        ({"file_busy": True}, FILE_IN_USE),
    ],
    ids=["teach-mode", "remote-off", "file-busy"],
)
def test_a_refused_load_changes_nothing_and_says_why_in_its_status_bytes(
    sim: YaskawaSimulator, controller: dict[str, object], added: int
) -> None:
    with file_client(sim) as client:
        saved = client.read_file("TOOL.CND")
    for key, value in controller.items():
        setattr(sim, key, value)
    changed = saved.replace(b"0.000,0.000,0.000,0.0000,0.0000,0.0000", b"1.000,0,0,0,0,0", 1)
    with file_client(sim) as client, pytest.raises(HsesError) as refused:
        client.write_file("TOOL.CND", changed)
    # yrcom reads byte 26 (the added status size, 1) as the status and bytes 30-31 (padding)
    # as the added status: "status 0x01, added 0x0000", as its notes say a live YRC1000 answered.
    assert (refused.value.status, refused.value.added) == (0x01, 0)
    reply = exchange(sim.file_port, request(2, 0x15, b"TOOL.CND"))
    assert status_bytes(reply) == (0x95, 0x1F, 1, added)
    assert sim.tool_cnd() == saved
    assert sim.loads_applied == 0


@pytest.mark.parametrize(
    ("cut", "added"),
    [
        (b"//TOOL 63", INCORRECT_NUMBER_OF_DATA),
        (b"///NAME STANDARD TOOL", CONDITION_FILE_RECORD),
    ],
    ids=["a-tool-missing", "a-block-malformed"],
)
def test_a_file_the_controller_cannot_read_is_refused_at_its_last_block(
    sim: YaskawaSimulator, cut: bytes, added: int
) -> None:
    saved = sim.tool_cnd()
    broken = saved[: saved.index(cut)] if cut.startswith(b"//TOOL") else saved.replace(cut, b"")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(TIMEOUT_S)
        sock.sendto(request(2, 0x15, b"TOOL.CND", request_id=3), (sim.host, sim.file_port))
        assert status_bytes(sock.recv(4096))[1] == 0
        blocks = [broken[i : i + 479] for i in range(0, len(broken), 479)]
        for number, data in enumerate(blocks, 1):
            flag = LAST_BLOCK if number == len(blocks) else 0
            sock.sendto(
                request(2, 0x15, data, ack=1, block=number | flag, request_id=3),
                (sim.host, sim.file_port),
            )
            reply = sock.recv(4096)
    assert status_bytes(reply)[1:] == (0x1F, 1, added)
    assert struct.unpack_from("<I", reply, 12)[0] == len(blocks) | LAST_BLOCK
    assert sim.tool_cnd() == saved
    assert sim.loads_applied == 0


def test_silence_after_the_last_load_block_leaves_the_file_loaded(sim: YaskawaSimulator) -> None:
    saved = sim.tool_cnd()
    changed = saved.replace(b"///NAME STANDARD TOOL", b"///NAME NEW", 1)
    sim.fault = go_silent("after", "load TOOL.CND last block")
    with file_client(sim) as client, pytest.raises(TimeoutError):
        client.write_file("TOOL.CND", changed)
    assert sim.stalled
    assert sim.tools[0].name == "NEW", "applied, then not answered"
    sim.stalled = False
    with file_client(sim) as client:
        assert client.read_file("TOOL.CND") == changed


def test_silence_before_a_load_block_leaves_the_file_as_it_was(sim: YaskawaSimulator) -> None:
    saved = sim.tool_cnd()
    sim.fault = go_silent("before", "load TOOL.CND block 2")
    with file_client(sim) as client, pytest.raises(TimeoutError):
        client.write_file("TOOL.CND", saved.replace(b"STANDARD", b"CHANGED"))
    sim.stalled = False
    assert sim.tool_cnd() == saved
    assert "load TOOL.CND block 2" in sim.requests
    assert "load TOOL.CND block 3" not in sim.requests


def test_a_transfer_left_behind_keeps_the_file_port_busy_until_it_times_out(
    sim: YaskawaSimulator,
) -> None:
    # A client asked for TOOL.CND, took its first block and went away without an ACK.
    reply = exchange(sim.file_port, request(2, 0x16, b"TOOL.CND"))
    assert struct.unpack_from("<I", reply, 12)[0] == 1
    busy = exchange(sim.file_port, request(2, 0x16, b"TOOL.CND"))
    assert status_bytes(busy) == (0x96, 0x1F, 1, 0xE444)
    with file_client(sim) as client:
        with pytest.raises(HsesError):
            client.read_file("TOOL.CND")
        time.sleep(sim.transfer_timeout_s + 0.1)
        assert client.read_file("TOOL.CND") == sim.tool_cnd()
    assert sim.transfers_timed_out == 1


def test_a_silent_position_read_times_yrcom_out(sim: YaskawaSimulator) -> None:
    sim.fault = go_silent("before", "position read")
    with robot_client(sim) as client:
        assert client.read_status()["play"]
        with pytest.raises(TimeoutError):
            client.read_position(101)
        with pytest.raises(TimeoutError):
            client.read_status()
    assert sim.stalled


def test_tool_cnd_cannot_be_deleted_and_another_file_can(sim: YaskawaSimulator) -> None:
    reply = exchange(sim.file_port, request(2, 0x09, b"TOOL.CND"))
    assert status_bytes(reply)[1:] == (0x1F, 1, 0xE2AF)
    with file_client(sim) as client:
        client.delete_file("WEAV.CND")
        assert client.list_files("*.CND") == ["TOOL.CND", "UFRAME.CND"]
