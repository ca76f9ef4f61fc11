"""app.vendors.yaskawa.hses_wire held to Yaskawa's HSES manual (*Options Instructions for
High-Speed Ethernet Server Function*, FS100 160766-1CD, chapter 3; its layout and codes as
masayuki-kono/moto-hses ``docs/specs/hses-protocol.md`` transcribes them): packets compared
with bytes laid out here from the manual's offsets (never with the module's own encoder),
the request ID's sequence, the resend and the deadline against a peer in this test that
counts what arrives, and the status tables against the manual's codes."""

from __future__ import annotations

import ast
import inspect
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import pytest

from app.vendors.connector import ControllerProtocolError, ControllerUnreachable, Deadline
from app.vendors.yaskawa import hses_wire
from app.vendors.yaskawa.hses_wire import (
    ADDED_STATUS_WORDS,
    BUSY,
    FILE_CONTROL,
    GET_ALL,
    MAX_DATA,
    ROBOT_CONTROL,
    STATUS_WORDS,
    Answer,
    HsesRefusal,
    UdpPort,
    answer_id,
    checked,
    parse_answer,
    request_packet,
    status_text,
)
from tests.controllers import yaskawa_sim

# --- the packet, byte by byte (manual 3.1, 3.2) ----------------------------------------------


def le(value: int, size: int) -> bytes:
    return value.to_bytes(size, "little")


def manual_header(data_size: int, division: int, ack: int, request_id: int, block: int) -> bytes:
    """Bytes 0-23: "YERC", header size 0x20 (WORD), data part size (WORD), reserve 0x03,
    processing division, ACK, request ID, block number (DWORD), "99999999"."""
    return (
        b"YERC"
        + le(0x20, 2)
        + le(data_size, 2)
        + bytes([0x03, division, ack, request_id])
        + le(block, 4)
        + b"99999999"
    )


def manual_answer(
    *,
    division: int = 1,
    request_id: int = 7,
    service: int = 0x81,
    status: int = 0,
    added_size: int = 0,
    added: int = 0,
    data: bytes = b"",
    block: int = 0x8000_0000,
    ack: int = 1,
    header_size: int = 0x20,
) -> bytes:
    """An answer: the header, then byte 24 the service + 0x80, 25 the status, 26 the added
    status size, 27 padding, 28-29 the added status, 30-31 padding, then the data part."""
    header = bytearray(manual_header(len(data), division, ack, request_id, block))
    header[4:6] = le(header_size, 2)
    sub = bytes([service, status, added_size, 0]) + le(added, 2) + b"\x00\x00"
    return bytes(header) + sub + data


def test_a_request_is_laid_out_as_the_manuals_3_1() -> None:
    packet = request_packet(
        ROBOT_CONTROL, 0x2A, command=0x75, instance=0x101, attribute=3, service=0x0E
    )
    expected = manual_header(0, 1, 0, 0x2A, 0) + (
        le(0x75, 2) + le(0x101, 2) + bytes([3, 0x0E]) + b"\x00\x00"  # padding: bytes 30-31
    )
    assert packet == expected


def test_a_file_transfers_block_carries_its_data_ack_and_block_number() -> None:
    data = b"//TOOL 0\r\n" * 3
    packet = request_packet(FILE_CONTROL, 255, service=0x15, data=data, ack=1, block=0x8000_0002)
    expected = manual_header(len(data), 2, 1, 255, 0x8000_0002) + b"\x00" * 4 + b"\x00\x15\x00\x00"
    assert packet == expected + data


def test_a_data_part_holds_at_most_479_bytes() -> None:
    """0x1DF bytes (manual 3.1); a larger part is refused before it is sent (the controller
    would answer E49E, frame size over)."""
    assert MAX_DATA == 0x1DF
    assert len(request_packet(FILE_CONTROL, 1, service=0x15, data=b"x" * 479)) == 32 + 479
    with pytest.raises(ValueError, match=r"^an HSES data part holds at most 479 bytes, not 480$"):
        request_packet(FILE_CONTROL, 1, service=0x15, data=b"x" * 480)


def test_an_answer_is_read_at_the_manuals_offsets() -> None:
    raw = manual_answer(request_id=9, service=0x81, data=b"\x01\x02\x03\x04", block=0x8000_0000)
    assert answer_id(raw) == 9
    assert parse_answer(raw, ROBOT_CONTROL, 0x01) == Answer(
        0x8000_0000, 0, None, b"\x01\x02\x03\x04"
    )
    refused = manual_answer(
        service=0x95, status=0x1F, added_size=1, added=0xE2B2, division=2, block=3
    )
    assert parse_answer(refused, FILE_CONTROL, 0x15) == Answer(3, 0x1F, 0xE2B2, b"")
    no_added = manual_answer(status=0x28, added_size=0, added=0x1234)
    assert parse_answer(no_added, ROBOT_CONTROL, 0x01).added is None


def test_an_answer_with_trailing_bytes_holds_its_announced_data_part() -> None:
    raw = manual_answer(data=b"ABCD") + b"junk"
    assert parse_answer(raw, ROBOT_CONTROL, 0x01).data == b"ABCD"


@pytest.mark.parametrize(
    ("raw", "said"),
    [
        (b"YERC" + b"\x00" * 20, "not an HSES answer"),
        (b"YERX" + manual_answer()[4:], "not an HSES answer"),
        (
            manual_answer(header_size=0x1F),
            "an HSES answer of header size 31, division 1, ACK 1, service 0x81 to a request of "
            "division 1, service 0x01",
        ),
        (manual_answer(division=2), "division 2, ACK 1, service 0x81 to a request of division 1"),
        (manual_answer(ack=0), "division 1, ACK 0, service 0x81"),
        (manual_answer(service=0x8E), "service 0x8E to a request of division 1, service 0x01"),
        (manual_answer(data=b"ABCD")[:-1], "an HSES answer announcing 4 bytes holds 3"),
    ],
    ids=["short", "magic", "header-size", "division", "ack", "service", "data-size"],
)
def test_what_is_not_the_answer_asked_for_is_a_protocol_error(raw: bytes, said: str) -> None:
    with pytest.raises(ControllerProtocolError) as error:
        parse_answer(raw, ROBOT_CONTROL, 0x01)
    assert said in str(error.value)


def test_the_answer_to_a_service_above_0x7f_wraps_in_its_byte() -> None:
    raw = manual_answer(service=(0xA0 + 0x80) & 0xFF)
    assert parse_answer(raw, ROBOT_CONTROL, 0xA0).status == 0


@pytest.mark.parametrize("raw", [b"", b"YERC", b"YERX" + bytes(28)])
def test_a_packet_that_is_not_an_answer_has_no_request_id(raw: bytes) -> None:
    assert answer_id(raw) is None


# --- a peer in the test: what arrives, and what it answers -------------------------------------


@dataclass
class Peer:
    """A UDP socket on loopback that records each datagram and answers what `reply` gives
    (nothing when it gives an empty list)."""

    sock: socket.socket
    received: list[bytes] = field(default_factory=list)
    replies: list[list[bytes]] = field(default_factory=list)
    stopped: threading.Event = field(default_factory=threading.Event)

    @property
    def port(self) -> int:
        port: int = self.sock.getsockname()[1]
        return port

    def serve(self) -> None:
        self.sock.settimeout(0.05)
        while not self.stopped.is_set():
            try:
                packet, address = self.sock.recvfrom(65535)
            except TimeoutError:
                continue
            except OSError:
                return
            self.received.append(packet)
            for reply in self.replies.pop(0) if self.replies else []:
                self.sock.sendto(reply, address)


@pytest.fixture
def peer() -> Iterator[Peer]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    served = Peer(sock)
    thread = threading.Thread(target=served.serve, daemon=True)
    thread.start()
    yield served
    served.stopped.set()
    thread.join(2.0)
    sock.close()


def status_request(request_id: int) -> bytes:
    return request_packet(ROBOT_CONTROL, request_id, command=0x72, instance=1, service=GET_ALL)


def ask_within(port: UdpPort, limit_s: float, *, resend: bool) -> tuple[object, float]:
    """`port.ask` in a thread of its own, given `limit_s` to return: (what it returned or
    raised, seconds taken). An ask that never returns fails the test at `limit_s` (its
    socket closed under it, which ends a send), not at pytest's own timeout."""
    outcome: list[object] = []
    started = time.monotonic()

    def run() -> None:
        try:
            outcome.append(port.ask(status_request, GET_ALL, resend=resend))
        except Exception as err:  # handed to the test
            outcome.append(err)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(limit_s)
    took = time.monotonic() - started
    if thread.is_alive():
        port.close()
        thread.join(2.0)
        pytest.fail(
            f"ask had not returned {limit_s} s after it began "
            f"(a {port._deadline.timeout_s} s deadline)"
        )
    return outcome[0], took


def test_request_ids_advance_by_one_and_wrap_in_their_byte(peer: Peer) -> None:
    port = UdpPort("127.0.0.1", peer.port, ROBOT_CONTROL, Deadline(2.0))
    try:
        ids = [port.next_id() for _ in range(300)]
    finally:
        port.close()
    assert ids == [n % 256 for n in range(1, 301)]


def test_each_new_request_carries_the_next_id_and_a_resend_the_same(peer: Peer) -> None:
    """Two asks: the first answered only after its resend, the second at once; the request
    ID at byte 11 is 1, 1 (the resend), then 2, and each answer is taken by its own ID."""
    peer.replies = [[], [manual_answer(request_id=1, data=b"one!")], [manual_answer(request_id=2)]]
    port = UdpPort("127.0.0.1", peer.port, ROBOT_CONTROL, Deadline(3.0))
    try:
        first, _ = ask_within(port, 3.0, resend=True)
        second, _ = ask_within(port, 3.0, resend=True)
    finally:
        port.close()
    assert first == (1, Answer(0x8000_0000, 0, None, b"one!"))
    assert isinstance(second, tuple)
    assert second[0] == 2
    assert [p[11] for p in peer.received] == [1, 1, 2]
    assert peer.received[0] == peer.received[1] == status_request(1)


def test_a_late_answer_to_another_request_and_a_stray_datagram_are_passed_over(peer: Peer) -> None:
    peer.replies = [
        [b"not hses", manual_answer(request_id=200), manual_answer(request_id=1, data=b"mine")]
    ]
    port = UdpPort("127.0.0.1", peer.port, ROBOT_CONTROL, Deadline(2.0))
    try:
        got, took = ask_within(port, 3.0, resend=False)
    finally:
        port.close()
    assert got == (1, Answer(0x8000_0000, 0, None, b"mine"))
    assert took < 1.0, "answered at once: the other datagrams were not waited on"
    assert len(peer.received) == 1


@pytest.mark.parametrize(("resend", "sends"), [(True, 2), (False, 1)])
def test_silence_is_unreachable_at_the_deadline(peer: Peer, resend: bool, sends: int) -> None:
    """A 0.4 s deadline: sent at 0 and (resending) again at RESEND_S = 0.25 s, then refused
    at 0.4 s. The test gives ask 3 s, so an ask that never gives up fails here."""
    port = UdpPort("127.0.0.1", peer.port, ROBOT_CONTROL, Deadline(0.4))
    try:
        got, took = ask_within(port, 3.0, resend=resend)
    finally:
        port.close()
    assert isinstance(got, ControllerUnreachable), got
    assert str(got) == (
        f"the controller did not answer on 127.0.0.1:{peer.port} (UDP) within 0.4 s (is its "
        "High Speed Ethernet Server enabled, on these ports?)"
    )
    assert 0.4 <= took < 0.4 + 0.5, took
    assert [p[11] for p in peer.received] == [1] * sends


def test_no_time_left_reads_nothing(peer: Peer) -> None:
    """A wait of 0 s, or a session whose deadline is spent, returns at once without a read
    (a socket given a 0 s timeout would not wait but raise, BlockingIOError)."""
    port = UdpPort("127.0.0.1", peer.port, ROBOT_CONTROL, Deadline(2.0))
    spent = UdpPort("127.0.0.1", peer.port, ROBOT_CONTROL, Deadline(0.0))
    try:
        assert port.receive(1, GET_ALL, 0.0) is None
        assert spent.receive(1, GET_ALL, 0.25) is None
        got, took = ask_within(spent, 3.0, resend=True)
    finally:
        port.close()
        spent.close()
    assert isinstance(got, ControllerUnreachable), got
    assert str(got).startswith(f"the controller did not answer on 127.0.0.1:{peer.port} (UDP)")
    assert took < 0.5, took


def test_a_closed_port_is_waited_out_like_silence() -> None:
    """ICMP port unreachable on loopback: ask waits to the deadline (no spin, no crash)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    closed = sock.getsockname()[1]
    sock.close()
    port = UdpPort("127.0.0.1", closed, ROBOT_CONTROL, Deadline(0.4))
    try:
        got, took = ask_within(port, 3.0, resend=True)
    finally:
        port.close()
    assert isinstance(got, ControllerUnreachable), got
    assert "did not answer" in str(got)
    assert 0.4 <= took < 0.9, took


def test_a_datagram_that_cannot_be_sent_is_unreachable(peer: Peer) -> None:
    port = UdpPort("127.0.0.1", peer.port, ROBOT_CONTROL, Deadline(1.0))
    try:
        with pytest.raises(ControllerUnreachable) as error:
            port.send(b"x" * 70_000)  # above UDP's 65507 bytes: EMSGSIZE
    finally:
        port.close()
    assert str(error.value) == f"127.0.0.1:{peer.port} (UDP): cannot send: Message too long"


class _Unreachable:
    """A socket whose receive meets an ICMP network unreachable."""

    def settimeout(self, _seconds: float) -> None:
        pass

    def recv(self, _size: int) -> bytes:
        raise OSError(101, "Network is unreachable")


def test_a_receive_error_other_than_a_refusal_is_unreachable(
    peer: Peer, monkeypatch: pytest.MonkeyPatch
) -> None:
    port = UdpPort("127.0.0.1", peer.port, ROBOT_CONTROL, Deadline(1.0))
    real = port._sock
    monkeypatch.setattr(port, "_sock", _Unreachable())
    try:
        with pytest.raises(ControllerUnreachable) as error:
            port.receive(1, GET_ALL, 0.5)
    finally:
        real.close()
    assert str(error.value) == f"127.0.0.1:{peer.port} (UDP): Network is unreachable"


def test_a_host_that_does_not_resolve_is_unreachable(monkeypatch: pytest.MonkeyPatch) -> None:
    def unknown(*_args: object, **_kwargs: object) -> None:
        raise socket.gaierror(-2, "Name or service not known")

    monkeypatch.setattr(socket, "getaddrinfo", unknown)
    with pytest.raises(ControllerUnreachable) as error:
        UdpPort("robot7.cell", 10040, ROBOT_CONTROL, Deadline(1.0))
    assert str(error.value) == "cannot reach robot7.cell:10040 (UDP): Name or service not known"


# --- the codes (manual 3.2: status; the added status table) ------------------------------------

#: Every added status code of the manual's table, by its hundreds as the table groups them.
# fmt: off
MANUAL_ADDED_CODES = frozenset({
    0x1010, 0x1011, 0x1012, 0x1013, 0x1020,
    0x2010, 0x2020, 0x2030, 0x2040, 0x2050, 0x2060, 0x2070, 0x2080, 0x2090, 0x2100,
    0x2110, 0x2120, 0x2130, 0x2150,
    0x3010, 0x3040, 0x3050, 0x3070, 0x3220, 0x3230, 0x3350, 0x3360, 0x3370, 0x3380,
    0x3390, 0x3400, 0x3410, 0x3420, 0x3430, 0x3450, 0x3460,
    0x4010, 0x4012, 0x4020, 0x4030, 0x4040, 0x4060, 0x4120, 0x4130, 0x4140, 0x4150,
    0x4170, 0x4190, 0x4200, 0x4230, 0x4420, 0x4430, 0x4480, 0x4490,
    0x5110, 0x5120, 0x5130, 0x5170, 0x5180, 0x5200, 0x5310, 0x5340, 0x5370, 0x5390,
    0x5430, 0x5480,
    0x6010, 0x6020, 0x6030, 0x6040, 0x6050, 0x6060, 0x6070, 0x6080, 0x6090, 0x6100,
    0x6110, 0x6120, 0x6130, 0x6140,
    0xA000, 0xA001, 0xA002, 0xA100, 0xA101,
    0xB001, 0xB002, 0xB003, 0xB004, 0xB005, 0xB006, 0xB007, 0xB008, 0xB009, 0xB00A,
    0xB00B, 0xB00C, 0xB00D, 0xB00E,
    0xC001, 0xC002, 0xC003, 0xC800, 0xCFFF,
    0xD8FA, 0xD8F1,
    0xE24F, 0xE250, 0xE289, 0xE28A, 0xE28B, 0xE28C, 0xE29C, 0xE2A0, 0xE2A7, 0xE2AA,
    0xE2AF, 0xE2B0, 0xE2B1, 0xE2B2, 0xE2B3, 0xE2B4, 0xE444, 0xE49D, 0xE49E, 0xE49F,
    0xE4A1, 0xE4A2, 0xE4A3, 0xE4A4, 0xE4A5, 0xE4A6, 0xE4A7, 0xE4A8, 0xE4A9,
    0xFFF0, 0xFFF2, 0xFFF3, 0xFFF4, 0xFFF5, 0xFFF6, 0xFFF7, 0xFFF8, 0xFFFE,
})
# fmt: on

#: What the manual says each code means, as words the module's sentence must hold: for
#: each code the module words.
MANUAL_MEANING: dict[int, tuple[str, ...]] = {
    0x1010: ("command error",),
    0x1011: ("number", "operands"),
    0x1012: ("operand value", "range"),
    0x1013: ("operand length",),
    0x1020: ("disk full",),
    0x2010: ("manipulator", "operating"),
    0x2020: ("hold", "programming pendant"),
    0x2030: ("hold", "playback panel"),
    0x2040: ("external hold",),
    0x2050: ("command hold",),
    0x2060: ("error", "alarm"),
    0x2070: ("servo", "off"),
    0x2080: ("incorrect mode",),
    0x2090: ("file", "another function"),
    0x2100: ("command remote", "not set"),
    0x2110: ("cannot be accessed",),
    0x2120: ("cannot be loaded",),
    0x2130: ("editing",),
    0x3070: ("current value not made",),
    0x3370: ("incorrect control group",),
    0x4020: ("job editing prohibited",),
    0x5170: ("format error",),
    0x5180: ("incorrect number of data",),
    0x5200: ("data range over",),
    0x5370: ("condition file",),
    0x6010: ("operation",),
    0x6020: ("memory", "device"),
    0x6030: ("device", "accessed"),
    0xA000: ("undefined command",),
    0xA001: ("instance",),
    0xA002: ("attribute",),
    0xB002: ("data use prohibited",),
    0xB003: ("data size",),
    0xB004: ("out of range",),
    0xB005: ("data undefined",),
    0xCFFF: ("other error",),
    0xD8F1: ("another command", "busy"),
    0xD8FA: ("exclusive", "busy"),
    0xE28B: ("receive timeout",),
    0xE28C: ("overwritten",),
    0xE29C: ("does not exist", "size"),
    0xE2A0: ("wrong",),
    0xE2A7: ("file list",),
    0xE2AF: ("cannot be deleted",),
    0xE2B2: ("remote is off",),
    0xE2B3: ("file not found",),
    0xE2B4: ("too long",),
    0xE444: ("another command", "busy"),
    0xE49D: ("data size 0",),
    0xE49E: ("frame size over",),
    0xE49F: ("frame size 0",),
    0xE4A1: ("block number",),
    0xE4A2: ("ack",),
    0xE4A3: ("processing division",),
    0xE4A4: ("access level",),
    0xE4A5: ("header size",),
    0xE4A6: ("identifier",),
    0xE4A7: ("sizes differ",),
    0xFFF6: ("too many requests", "busy"),
    0xFFFE: ("remote mode", "cut"),
}

#: The codes the manual's table says are a busy controller ("BUSY condition", "BUSY or
#: Semaphore error"), which an ask again may outlast.
MANUAL_BUSY = frozenset({0xD8F1, 0xD8FA, 0xE444, 0xFFF6})


def test_every_added_status_worded_is_a_code_of_the_manuals_table() -> None:
    assert sorted(set(ADDED_STATUS_WORDS) - MANUAL_ADDED_CODES) == []


@pytest.mark.parametrize("code", sorted(MANUAL_MEANING), ids=lambda c: f"{c:04X}")
def test_each_added_status_is_told_in_the_manuals_meaning(code: int) -> None:
    said = status_text(0x1F, code)
    assert said.startswith(f"status 0x1F, added status 0x{code:04X}: ")
    words = ADDED_STATUS_WORDS[code].lower()
    missing = [w for w in MANUAL_MEANING[code] if w not in words]
    assert missing == [], f"0x{code:04X} {words!r} does not say {missing}"
    assert said.endswith(ADDED_STATUS_WORDS[code])


def test_the_table_loses_no_code_to_a_key_written_twice() -> None:
    """A dict literal keeps the last of two equal keys: one code's words would vanish."""
    tree = ast.parse(inspect.getsource(hses_wire))
    tables = {
        node.target.id: node.value
        for node in tree.body
        if isinstance(node, ast.AnnAssign)
        and isinstance(node.target, ast.Name)
        and isinstance(node.value, ast.Dict)
    }
    for name in ("STATUS_WORDS", "ADDED_STATUS_WORDS"):
        keys = [ast.literal_eval(key) for key in tables[name].keys if key is not None]
        assert len(keys) == len(set(keys)), name


def test_the_busy_codes_are_the_manuals_busy_ones() -> None:
    assert BUSY == MANUAL_BUSY
    assert all("busy" in ADDED_STATUS_WORDS[code] for code in BUSY)


def test_every_added_status_the_simulator_answers_is_worded() -> None:
    """The simulator (written from the manuals) answers these; each has its words."""
    answered = {
        value
        for name, value in vars(yaskawa_sim).items()
        if name.isupper()
        and isinstance(value, int)
        and 0x1000 <= value <= 0xFFFF
        and value in MANUAL_ADDED_CODES
    }
    assert len(answered) >= 16, sorted(hex(c) for c in answered)
    assert sorted(answered - set(ADDED_STATUS_WORDS)) == []


@pytest.mark.parametrize(
    ("status", "meaning"),
    [
        (0x08, "command is not defined"),
        (0x09, "element number"),
        (0x1F, "added status"),
        (0x28, "instance"),
    ],
)
def test_the_statuses_without_an_added_status_are_the_manuals(status: int, meaning: str) -> None:
    """Manual 3.2, byte 25: 0x1F abnormal (see the added status), 0x08 command not defined,
    0x09 invalid element number, 0x28 instance not present."""
    assert meaning in STATUS_WORDS[status]
    assert status_text(status, None) == f"status 0x{status:02X}: {STATUS_WORDS[status]}"


def test_codes_outside_the_tables_are_said_to_be_so() -> None:
    assert set(STATUS_WORDS) == {0x08, 0x09, 0x1F, 0x28}
    assert status_text(0x07, None) == "status 0x07: unknown status"
    assert status_text(0x1F, 0x1234) == (
        "status 0x1F, added status 0x1234: not in the HSES manual's added status table"
    )


def test_a_refusal_holds_its_codes_and_checked_passes_status_0() -> None:
    ok = Answer(1, 0, None, b"data")
    assert checked(ok) is ok
    with pytest.raises(HsesRefusal) as refusal:
        checked(Answer(0, 0x1F, 0x2080, b""))
    assert (refusal.value.status, refusal.value.added) == (0x1F, 0x2080)
    assert str(refusal.value) == "status 0x1F, added status 0x2080: incorrect mode"
    with pytest.raises(HsesRefusal) as bare:
        checked(Answer(0, 0x28, None, b""))
    assert bare.value.added is None
    assert str(bare.value) == "status 0x28: the instance of the requested data does not exist"
