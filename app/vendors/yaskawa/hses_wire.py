"""Yaskawa High Speed Ethernet Server (HSES) packets over UDP, under one deadline.

Followed: Yaskawa's *Options Instructions for High-Speed Ethernet Server Function* (FS100
160766-1CD; the DX100 162529-1CD, DX200 165304-1CD and YRC1000 165838-1CD editions keep its
chapter 3): the 32-byte header (``"YERC"``, header size 0x20, data size, 0x03, processing
division 1 robot control / 2 file control, ACK 0 request / 1 answer, request ID, block
number, ``"99999999"``), a request's sub-header (command, instance, attribute, service,
padding) and an answer's (service + 0x80, status, added status size, padding, added status,
padding: the status at byte 25, the added status at 28-29, as the manual's 3.2.1 example and
hsinkoyu/fs100 read them; yrcom 0.3.1 reads bytes 26 and 30-31, and so reports every refusal
as "status 0x01, added 0x0000"). Data parts hold at most 479 bytes. File control (3.4): a
save's or list's blocks are each acknowledged by echoing the block number, the last block's
number carrying 0x8000_0000; a load's request is answered by an ACK of block 0, then each
block sent is answered with its number.

UDP has no session: `UdpPort.ask` sends a request again (with its request ID, so a late
answer still matches) when no answer came within `RESEND_S`, until the deadline, when asked
to (the connector does so for robot control reads, which change nothing); a load's data
blocks are sent once (a block sent twice is a block number error to the controller). The
words for the status and added status codes are the manual's table (transcribed in
masayuki-kono/moto-hses ``docs/specs/hses-protocol.md``).
"""

from __future__ import annotations

import contextlib
import socket
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass

from app.vendors.connector import ControllerProtocolError, ControllerUnreachable, Deadline

MAGIC = b"YERC"
HEADER_SIZE = 0x20
MAX_DATA = 479
LAST_BLOCK = 0x8000_0000
ROBOT_CONTROL = 1
FILE_CONTROL = 2
GET_ALL = 0x01
GET_SINGLE = 0x0E
FILE_LOAD = 0x15
FILE_SAVE = 0x16
FILE_LIST = 0x32
#: how long an answer is waited for before the request is sent again (within the deadline)
RESEND_S = 0.25
_HEADER = struct.Struct("<4sHHBBBBI8s")
_REQUEST_SUB = struct.Struct("<HHBBH")
_ANSWER_SUB = struct.Struct("<BBBBHH")

#: The manual's status codes (an answer's byte 25).
STATUS_WORDS: dict[int, str] = {
    0x08: "requested command is not defined",
    0x09: "the element number of the data is invalid",
    0x1F: "abnormal answer (see the added status)",
    0x28: "the instance of the requested data does not exist",
}

#: The manual's added status codes (an answer's bytes 28-29), in words.
ADDED_STATUS_WORDS: dict[int, str] = {
    0x1010: "command error",
    0x1011: "error in the number of command operands",
    0x1012: "command operand value out of range",
    0x1013: "command operand length error",
    0x1020: "disk full of files",
    0x2010: "the manipulator is operating",
    0x2020: "hold by the programming pendant",
    0x2030: "hold by the playback panel",
    0x2040: "external hold",
    0x2050: "command hold",
    0x2060: "an error or alarm is occurring",
    0x2070: "servo is off",
    0x2080: "incorrect mode",
    0x2090: "the file is being accessed by another function",
    0x2100: "command remote is not set",
    0x2110: "this data cannot be accessed",
    0x2120: "this data cannot be loaded",
    0x2130: "editing",
    0x3070: "current value not made",
    0x3370: "incorrect control group",
    0x4020: "job editing prohibited",
    0x5170: "format error",
    0x5180: "incorrect number of data",
    0x5200: "data range over",
    0x5370: "error in a condition file data record",
    0x6010: "the robot or station is in operation",
    0x6020: "not enough memory on the device",
    0x6030: "the device cannot be accessed",
    0xA000: "undefined command",
    0xA001: "instance error",
    0xA002: "attribute error",
    0xB002: "data use prohibited",
    0xB003: "requested data size error",
    0xB004: "data out of range",
    0xB005: "data undefined",
    0xCFFF: "other error",
    0xD8F1: "processing another command (busy)",
    0xD8FA: "transmission exclusive error (busy or semaphore)",
    0xE28B: "the communication was cut at a receive timeout",
    0xE28C: "the target file cannot be overwritten",
    0xE29C: "the requested file does not exist or its size is 0",
    0xE2A0: "wrong requested path",
    0xE2A7: "the file is not in the requested file list",
    0xE2AF: "the file cannot be deleted",
    0xE2B2: "a file was sent or requested while remote is OFF",
    0xE2B3: "file not found",
    0xE2B4: "the requested path is too long",
    0xE444: "processing another command (busy)",
    0xE49D: "format error (data size 0)",
    0xE49E: "format error (frame size over)",
    0xE49F: "format error (frame size 0)",
    0xE4A1: "format error (block number error)",
    0xE4A2: "format error (ACK error)",
    0xE4A3: "format error (processing division error)",
    0xE4A4: "format error (access level error)",
    0xE4A5: "format error (header size error)",
    0xE4A6: "format error (identifier error)",
    0xE4A7: "format error (request and frame sizes differ)",
    0xFFF6: "too many requests to process (busy)",
    0xFFFE: "remote mode detected: the communication was cut",
}

#: Added status codes that mean "busy now, ask again".
BUSY = frozenset({0xD8F1, 0xD8FA, 0xE444, 0xFFF6})


def status_text(status: int, added: int | None) -> str:
    """The controller's codes in words: "status 0x1F, added status 0x2080: incorrect mode"."""
    if added is None:
        return f"status 0x{status:02X}: {STATUS_WORDS.get(status, 'unknown status')}"
    words = ADDED_STATUS_WORDS.get(added, "not in the HSES manual's added status table")
    return f"status 0x{status:02X}, added status 0x{added:04X}: {words}"


class HsesRefusal(Exception):
    """An answer with a non-zero status: the controller's `status` and `added` status."""

    def __init__(self, status: int, added: int | None) -> None:
        super().__init__(status_text(status, added))
        self.status = status
        self.added = added


@dataclass(frozen=True)
class Answer:
    """An answer's block number, status, added status and data part."""

    block: int
    status: int
    added: int | None
    data: bytes


def request_packet(
    division: int,
    request_id: int,
    *,
    command: int = 0,
    instance: int = 0,
    attribute: int = 0,
    service: int,
    data: bytes = b"",
    ack: int = 0,
    block: int = 0,
) -> bytes:
    """A request (or, `ack` 1, a file transfer's block or acknowledgement)."""
    if len(data) > MAX_DATA:
        raise ValueError(f"an HSES data part holds at most {MAX_DATA} bytes, not {len(data)}")
    header = _HEADER.pack(
        MAGIC, HEADER_SIZE, len(data), 3, division, ack, request_id, block, b"99999999"
    )
    return header + _REQUEST_SUB.pack(command, instance, attribute, service, 0) + data


def answer_id(packet: bytes) -> int | None:
    """The request ID an HSES answer echoes; None for a packet that is not one."""
    if len(packet) < HEADER_SIZE or packet[:4] != MAGIC:
        return None
    return packet[11]


def parse_answer(packet: bytes, division: int, service: int) -> Answer:
    """An HSES answer to `service` in `division`; ControllerProtocolError when it is not."""
    if len(packet) < HEADER_SIZE or packet[:4] != MAGIC:
        raise ControllerProtocolError(f"not an HSES answer: {packet[:32]!r}")
    _, size, data_size, _, div, ack, _, block, _ = _HEADER.unpack_from(packet)
    answered, status, added_size, _, added, _ = _ANSWER_SUB.unpack_from(packet, 24)
    if size != HEADER_SIZE or div != division or ack != 1 or answered != (service + 0x80) & 0xFF:
        raise ControllerProtocolError(
            f"an HSES answer of header size {size}, division {div}, ACK {ack}, service "
            f"0x{answered:02X} to a request of division {division}, service 0x{service:02X}"
        )
    data = packet[HEADER_SIZE : HEADER_SIZE + data_size]
    if len(data) != data_size:
        raise ControllerProtocolError(
            f"an HSES answer announcing {data_size} bytes holds {len(data)}"
        )
    return Answer(block, status, added if added_size else None, data)


class UdpPort:
    """One HSES service (robot control or file control) at host:port, over a connected UDP
    socket (so only that address's datagrams arrive, and a closed port shows)."""

    def __init__(self, host: str, port: int, division: int, deadline: Deadline) -> None:
        self.peer = f"{host}:{port} (UDP)"
        self.division = division
        self._request_id = 0
        try:
            infos = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
            family, kind, proto, _, address = infos[0]
            self._sock = socket.socket(family, kind, proto)
            self._sock.connect(address)
        except OSError as err:
            raise ControllerUnreachable(f"cannot reach {self.peer}: {err.strerror or err}") from err
        self._deadline = deadline

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._sock.close()

    def next_id(self) -> int:
        """A request ID for a new request (0-255, wrapping)."""
        self._request_id = (self._request_id + 1) % 256
        return self._request_id

    def send(self, packet: bytes) -> None:
        try:
            self._sock.send(packet)
        except OSError as err:
            raise ControllerUnreachable(f"{self.peer}: cannot send: {err.strerror or err}") from err

    def receive(self, request_id: int, service: int, wait_s: float) -> Answer | None:
        """The answer to request `request_id` arriving within `wait_s` (and the deadline), or
        None; answers to other requests (late ones) are passed over."""
        end = min(wait_s, self._deadline.left())
        deadline = Deadline(end)
        while deadline.left() > 0:
            self._sock.settimeout(deadline.left())
            try:
                packet = self._sock.recv(65535)
            except TimeoutError:
                return None
            except ConnectionRefusedError:
                # ICMP port unreachable: nothing listens there (yet). Waited out like
                # silence, so the resends keep their pace instead of spinning.
                time.sleep(deadline.left())
                return None
            except OSError as err:
                raise ControllerUnreachable(f"{self.peer}: {err.strerror or err}") from err
            if answer_id(packet) == request_id:  # a late answer to another request: passed
                return parse_answer(packet, self.division, service)
        return None

    def ask(
        self, packet_for: Callable[[int], bytes], service: int, *, resend: bool
    ) -> tuple[int, Answer]:
        """Send a new request (`packet_for` its request ID) and return (the ID, its answer),
        sending it again every `RESEND_S` while none came (when `resend`), until the
        deadline: ControllerUnreachable then."""
        request_id = self.next_id()
        packet = packet_for(request_id)
        while True:
            self.send(packet)
            wait = RESEND_S if resend else self._deadline.left()
            answer = self.receive(request_id, service, wait)
            if answer is not None:
                return request_id, answer
            if self._deadline.left() <= 0:
                raise ControllerUnreachable(
                    f"the controller did not answer on {self.peer} within "
                    f"{self._deadline.timeout_s:g} s (is its High Speed Ethernet Server "
                    "enabled, on these ports?)"
                )


def checked(answer: Answer) -> Answer:
    """The answer, or HsesRefusal with its codes when its status is not 0."""
    if answer.status != 0:
        raise HsesRefusal(answer.status, answer.added)
    return answer
