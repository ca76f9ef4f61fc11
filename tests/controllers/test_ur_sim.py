"""The UR simulator (ur_sim.py) holds to what UR's clients expect: the ur-rtde PyPI client
reads it and sends it programs (in a child process: the C++ extension blocks, and a hang must
fail the test, not the run), and raw RTDE and secondary conversations show its answers, its
refusals and its faults."""

from __future__ import annotations

import multiprocessing
import queue
import socket
import struct
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from tests.controllers.simbase import go_silent
from tests.controllers.ur_sim import (
    DATA_PACKAGE,
    GET_URCONTROL_VERSION,
    REQUEST_PROTOCOL_VERSION,
    SETUP_INPUTS,
    SETUP_OUTPUTS,
    START,
    TEXT_MESSAGE,
    UrSimulator,
    split_programs,
)
from tests.polling import wait_for

CHILD_TIMEOUT_S = 30.0
TCP = (0.01, -0.02, 0.15, 0.0, 0.0, 1.2)
SCRIPT = (
    "sec tcpcal_tcp():\n"
    f"  set_tcp(p[{', '.join(str(v) for v in TCP)}])\n"
    "  set_payload(1.5, [0.0, 0.0, 0.05])\n"
    "end\n"
)


# --- ur-rtde in a child process ----------------------------------------------------------


def _in_child(target: Callable[..., None], *args: object) -> list[object]:
    """What `target(*args, results)` put on its queue, run in a spawned process that must end
    within CHILD_TIMEOUT_S (killed and failed otherwise)."""
    context = multiprocessing.get_context("spawn")
    results = context.Queue()
    process = context.Process(target=target, args=(*args, results), daemon=True)
    process.start()
    process.join(CHILD_TIMEOUT_S)
    if process.is_alive():
        process.kill()
        process.join(5)
        pytest.fail(f"the ur-rtde client did not end within {CHILD_TIMEOUT_S} s")
    got: list[object] = []
    while True:
        try:
            got.append(results.get(timeout=0.5))
        except queue.Empty:
            break
    assert process.exitcode == 0, (process.exitcode, got)
    return got


def _read_and_send(host: str, secondary_port: int, out: multiprocessing.Queue[object]) -> None:
    import rtde_receive  # type: ignore[import-not-found]
    import script_client  # type: ignore[import-not-found]

    receive = rtde_receive.RTDEReceiveInterface(host)  # every default variable, 500 Hz
    read = {
        "pose": receive.getActualTCPPose(),
        "joints": receive.getActualQ(),
        "payload": receive.getPayload(),
        "modes": (receive.getRobotMode(), receive.getSafetyMode()),
    }
    client = script_client.ScriptClient(host, 5, 15, secondary_port)
    client.connect()
    client.sendScriptCommand(SCRIPT)
    deadline = time.monotonic() + 5
    while receive.getPayload() != 1.5 and time.monotonic() < deadline:
        time.sleep(0.01)
    read |= {
        "pose_after": receive.getActualTCPPose(),
        "payload_after": receive.getPayload(),
        "cog_after": receive.getPayloadCog(),
    }
    out.put(read)
    client.disconnect()
    receive.disconnect()


def _unknown_variable(host: str, out: multiprocessing.Queue[object]) -> None:
    import rtde_receive

    try:
        rtde_receive.RTDEReceiveInterface(host, 50.0, ["actual_q", "no_such_variable"])
    except RuntimeError as exc:
        out.put(str(exc))


def test_ur_rtde_reads_the_robot_and_its_script_sets_the_live_tcp() -> None:
    sim = UrSimulator.on_real_ports()
    try:
        sim.set_flange((400.0, -100.0, 500.0), np.diag([1.0, -1.0, -1.0]))
        sim.set_joints(10, -90, 90, -90, -90, 0)
        (got,) = _in_child(_read_and_send, sim.host, sim.secondary_port)
    finally:
        sim.stop()
    assert isinstance(got, dict)
    assert got["pose"] == pytest.approx([0.4, -0.1, 0.5, np.pi, 0.0, 0.0])
    assert got["joints"] == pytest.approx(np.radians([10, -90, 90, -90, -90, 0]))
    assert got["payload"] == 0.0
    assert got["modes"] == (7, 1)  # RUNNING, NORMAL
    assert got["payload_after"] == 1.5
    assert got["cog_after"] == pytest.approx([0.0, 0.0, 0.05])
    # the flange (z down) times the new TCP: 10 mm along x, 20 mm along +y, 150 mm down
    assert got["pose_after"][:3] == pytest.approx([0.41, -0.08, 0.35])
    assert sim.tcp() == TCP
    assert [p.kind for p in sim.programs] == ["sec"]
    assert sim.program_running  # a sec program runs beside the program


def test_ur_rtde_is_told_which_variable_the_controller_does_not_serve() -> None:
    sim = UrSimulator.on_real_ports()
    try:
        (message,) = _in_child(_unknown_variable, sim.host)
    finally:
        sim.stop()
    assert "[no_such_variable]" in str(message)


# --- a raw RTDE client and secondary reader -------------------------------------------------


class Rtde:
    """Just enough of an RTDE client to look at the simulator's answers."""

    def __init__(self, sim: UrSimulator) -> None:
        self.sock = socket.create_connection((sim.host, sim.rtde_port), timeout=2)
        self.buffer = b""

    def send(self, kind: int, payload: bytes = b"") -> None:
        self.sock.sendall(struct.pack(">HB", 3 + len(payload), kind) + payload)

    def package(self, kind: int | None = None, timeout: float = 2.0) -> tuple[int, bytes]:
        """The next package (of `kind`, skipping others)."""
        deadline = time.monotonic() + timeout
        while True:
            while len(self.buffer) >= 3:
                size, got = struct.unpack_from(">HB", self.buffer)
                if len(self.buffer) < size:
                    break
                payload, self.buffer = self.buffer[3:size], self.buffer[size:]
                if kind is None or got == kind:
                    return got, payload
            self.sock.settimeout(max(0.01, deadline - time.monotonic()))
            chunk = self.sock.recv(65536)
            if not chunk:
                raise ConnectionError("closed")
            self.buffer += chunk

    def ask(self, kind: int, payload: bytes = b"") -> bytes:
        self.send(kind, payload)
        return self.package(kind)[1]

    def outputs(self, names: list[str], frequency: float = 100.0) -> tuple[int, list[str]]:
        answer = self.ask(SETUP_OUTPUTS, struct.pack(">d", frequency) + ",".join(names).encode())
        return answer[0], answer[1:].decode().split(",")

    def drain(self) -> None:
        """Forget every byte sent so far (what was in flight before a fault)."""
        self.sock.settimeout(0.05)
        deadline = time.monotonic() + 1
        try:
            while self.sock.recv(65536) and time.monotonic() < deadline:
                pass
        except TimeoutError:
            pass
        self.buffer = b""

    def close(self) -> None:
        self.sock.close()


def _vector6(payload: bytes, offset: int = 1) -> tuple[float, ...]:
    return struct.unpack_from(">6d", payload, offset)


@pytest.fixture
def sim() -> Iterator[UrSimulator]:
    with UrSimulator() as running:
        yield running


@pytest.fixture
def rtde(sim: UrSimulator) -> Iterator[Rtde]:
    client = Rtde(sim)
    assert client.ask(REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
    yield client
    client.close()


def _streaming_tcp_offset(rtde: Rtde) -> None:
    assert rtde.outputs(["tcp_offset", "timestamp"], 200.0) == (1, ["VECTOR6D", "DOUBLE"])
    assert rtde.ask(START) == b"\x01"


def _tcp_offset_after_now(rtde: Rtde, sim: UrSimulator) -> tuple[float, ...]:
    """tcp_offset of the first package of the cycle after this moment (its `timestamp`, on
    the controller's clock), skipping those queued before it: whatever a loaded machine
    left in the socket carries the values of its own cycle."""
    now = time.monotonic() - sim.started_at
    while True:
        payload = rtde.package(DATA_PACKAGE)[1]
        if struct.unpack_from(">d", payload, 49)[0] >= now:
            return _vector6(payload)


def _secondary(sim: UrSimulator) -> socket.socket:
    return socket.create_connection((sim.host, sim.secondary_port), timeout=2)


def _robot_messages(sock: socket.socket, seconds: float) -> list[tuple[int, bytes]]:
    """Every ROBOT_MESSAGE (type, body after the ``>QbB`` head) within `seconds`."""
    found: list[tuple[int, bytes]] = []
    buffer = b""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        sock.settimeout(max(0.01, deadline - time.monotonic()))
        try:
            chunk = sock.recv(65536)
        except TimeoutError:
            break
        if not chunk:
            break
        buffer += chunk
        while len(buffer) >= 5:
            size, kind = struct.unpack_from(">iB", buffer)
            if len(buffer) < size:
                break
            body, buffer = buffer[5:size], buffer[size:]
            if kind == 20:
                found.append((body[9], body[10:]))
    return found


def test_the_version_answers_and_the_types_of_an_output_recipe(
    sim: UrSimulator, rtde: Rtde
) -> None:
    assert struct.unpack(">IIII", rtde.ask(GET_URCONTROL_VERSION)) == sim.version
    recipe, types = rtde.outputs(["actual_TCP_pose", "tcp_offset", "actual_q", "timestamp", ""])
    assert (recipe, types) == (1, ["VECTOR6D", "VECTOR6D", "VECTOR6D", "DOUBLE"])
    assert rtde.outputs(["robot_mode", "whatever"]) == (0, ["INT32", "NOT_FOUND"])


def test_a_controller_before_5_5_1_does_not_serve_tcp_offset() -> None:
    with UrSimulator(version=(5, 4, 3, 0)) as old:
        client = Rtde(old)
        client.ask(REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2))
        assert client.outputs(["actual_TCP_pose", "tcp_offset"]) == (0, ["VECTOR6D", "NOT_FOUND"])
        client.close()


def test_protocol_1_is_not_accepted(sim: UrSimulator) -> None:
    client = Rtde(sim)
    assert client.ask(REQUEST_PROTOCOL_VERSION, struct.pack(">H", 1)) == b"\x00"
    client.close()


def test_data_packages_come_at_the_recipe_frequency_and_carry_its_values(
    sim: UrSimulator, rtde: Rtde
) -> None:
    sim.pendant_set_tcp(TCP)
    assert rtde.outputs(["tcp_offset", "robot_mode", "timestamp"], 50.0)[0] == 1
    assert rtde.ask(START) == b"\x01"
    payloads, arrived = [], []
    for _ in range(11):
        payloads.append(rtde.package(DATA_PACKAGE)[1])
        arrived.append(time.monotonic())
    # 10 periods of 20 ms after the first on the controller's own clock (`timestamp`, s since
    # it started), which a loaded machine does not stretch as it does the wall clock's
    stamps = np.array([struct.unpack_from(">d", p, 53)[0] for p in payloads])
    assert np.allclose(np.diff(stamps), 0.02, rtol=0.0, atol=1e-9), np.diff(stamps)
    # and none arrives before its time (both clocks are this process's monotonic one)
    assert all(at >= sim.started_at + stamp for at, stamp in zip(arrived, stamps, strict=True))
    assert payloads[0][0] == 1
    assert _vector6(payloads[-1]) == TCP
    assert struct.unpack_from(">i", payloads[-1], 49) == (7,)


def test_a_pendant_change_and_a_program_start_show_in_tcp_offset(
    sim: UrSimulator, rtde: Rtde
) -> None:
    _streaming_tcp_offset(rtde)
    sim.pendant_set_tcp((0.0, 0.0, 0.1, 0.0, 0.0, 0.0))
    assert _tcp_offset_after_now(rtde, sim) == (0.0, 0.0, 0.1, 0.0, 0.0, 0.0)
    with _secondary(sim) as sock:
        sock.sendall(SCRIPT.encode())
        _robot_messages(sock, 0.2)
    assert sim.tcp() == TCP
    sim.play_program()  # the program starts with the installation's TCP
    assert _tcp_offset_after_now(rtde, sim) == (0.0, 0.0, 0.1, 0.0, 0.0, 0.0)


def test_a_text_message_reaches_an_rtde_client(sim: UrSimulator, rtde: Rtde) -> None:
    _streaming_tcp_offset(rtde)
    sim.say("Protective stop (C153A0)", level=1)
    payload = rtde.package(TEXT_MESSAGE)[1]
    length = payload[0]
    assert payload[1 : 1 + length] == b"Protective stop (C153A0)"
    source_length = payload[1 + length]
    assert payload[2 + length : 2 + length + source_length] == b"URControl"
    assert payload[-1] == 1


def test_the_secondary_interface_opens_with_its_version(sim: UrSimulator) -> None:
    with _secondary(sim) as sock:
        messages = _robot_messages(sock, 0.3)
    kind, body = messages[0]
    assert kind == 3
    name_length = body[0]
    assert body[1 : 1 + name_length] == b"URControl"
    assert struct.unpack_from(">BBii", body, 1 + name_length) == sim.version


def test_a_def_program_stops_the_running_program_a_sec_one_does_not(sim: UrSimulator) -> None:
    with _secondary(sim) as sock:
        sock.sendall(SCRIPT.encode())
        _robot_messages(sock, 0.2)
        assert sim.program_running
        sock.sendall(SCRIPT.replace("sec ", "def ").encode())
        _robot_messages(sock, 0.2)
    assert not sim.program_running
    assert [p.applied for p in sim.programs] == [True, True]


def test_in_local_control_a_program_is_ignored_with_c210(sim: UrSimulator) -> None:
    sim.remote_control(False)
    with _secondary(sim) as sock:
        sock.sendall(SCRIPT.encode())
        messages = _robot_messages(sock, 0.3)
    assert sim.tcp() == (0.0,) * 6
    (body,) = [b for kind, b in messages if kind == 6]
    assert struct.unpack_from(">iii", body) == (210, 0, 3)  # C210A0, VIOLATION
    assert b"remote control" in body[20:]


def test_in_a_protective_stop_a_program_is_ignored_and_rtde_shows_the_stop(
    sim: UrSimulator, rtde: Rtde
) -> None:
    sim.protective_stop()
    assert rtde.outputs(["safety_mode"], 100.0)[0] == 1
    rtde.ask(START)
    assert struct.unpack_from(">i", rtde.package(DATA_PACKAGE)[1], 1) == (3,)
    with _secondary(sim) as sock:
        sock.sendall(SCRIPT.encode())
        messages = _robot_messages(sock, 0.3)
    assert sim.tcp() == (0.0,) * 6
    assert (0, b"Protective stop: program not started") in messages


def test_a_tcp_that_is_not_a_pose_is_a_runtime_exception(sim: UrSimulator) -> None:
    with _secondary(sim) as sock:
        sock.sendall(b"sec bad():\n  set_tcp(p[0.1, 0.2])\nend\n")
        messages = _robot_messages(sock, 0.3)
    assert [kind for kind, _ in messages if kind == 10] == [10]
    assert sim.tcp() == (0.0,) * 6


@pytest.mark.parametrize(("moment", "applied"), [("before", False), ("after", True)])
def test_silent_at_the_script_no_package_leaves_any_connection(
    sim: UrSimulator, rtde: Rtde, moment: str, applied: bool
) -> None:
    _streaming_tcp_offset(rtde)
    rtde.package(DATA_PACKAGE)
    sim.fault = go_silent(moment, "script")  # type: ignore[arg-type]
    with _secondary(sim) as sock:
        _robot_messages(sock, 0.15)  # the version and state packages while it answers
        sock.sendall(SCRIPT.encode())
        # until the fault has fired (a fixed 0.1 s was not always enough on a loaded machine)
        wait_for(lambda: sim.stalled, 10, "the controller to go silent at the script")
        rtde.drain()
        with pytest.raises(TimeoutError):
            rtde.package(DATA_PACKAGE, timeout=0.3)
        assert _robot_messages(sock, 0.3) == []
    assert sim.stalled
    assert (sim.tcp() == TCP) is applied
    sim.stalled = False  # the controller answers again
    rtde.package(DATA_PACKAGE)


def test_a_session_left_behind_holds_its_inputs(sim: UrSimulator, rtde: Rtde) -> None:
    sim.hold_inputs("input_int_register_24")
    answer = rtde.ask(SETUP_INPUTS, b"input_int_register_24,input_int_register_25")
    assert answer == b"\x00IN_USE,INT32"
    assert rtde.outputs(["tcp_offset"])[0] == 1  # outputs are every client's to read


def test_open_connections_counts_what_clients_left_open(sim: UrSimulator) -> None:
    client = Rtde(sim)
    sock = _secondary(sim)
    wait_for(
        lambda: sim.open_connections() == {"rtde": 1, "secondary": 1},
        10,
        "the simulator to hold both connections",
    )
    client.close()
    sock.close()
    deadline = time.monotonic() + 2
    while sim.open_connections() != {"rtde": 0, "secondary": 0} and time.monotonic() < deadline:
        time.sleep(0.01)
    assert sim.open_connections() == {"rtde": 0, "secondary": 0}


def test_programs_are_split_where_urcontrol_splits_them() -> None:
    text = "sec a():\n  set_tcp(p[0,0,0,0,0,0])\nend\nset_payload(1.0)\ndef b():\n  x = 1\n"
    programs, rest = split_programs(text)
    assert [(p.kind, p.text) for p in programs] == [
        ("sec", "sec a():\n  set_tcp(p[0,0,0,0,0,0])\nend\n"),
        ("line", "set_payload(1.0)\n"),
    ]
    assert rest == "def b():\n  x = 1\n"  # waits for its end
