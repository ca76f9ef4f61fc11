"""What every controller connector offers: the session, its deadline, its errors, what it reads.

A connector reads and writes one tool's frame (the TCP: where the tool's working point is
and how it is oriented in the flange frame) and one of the robot's frames (contract v1.4
"Frames at the controller": a base or a fixed tool, a pose in the robot's base frame) in a
robot controller, over the controller's own wire protocol. A controller no remote interface
of which writes frames raises `FrameWriterMissing` saying why and which file to load by
hand. No database and no HTTP framework here: the service that deploys or
reconciles runs a connector in a worker thread and owns everything else.

Every connector converts through `app.kinematics.poses` (scipy Rotation), so the values a
controller holds in its own convention (its maker's pose format: app.words.PoseFormat) and the
quaternion tcpcal holds are one rotation. A session keeps to one deadline (`Deadline`),
started when it is opened (`connect(settings)`) and shared by every wait after it: connect,
login, mastership, each read and write, the read-back. A controller that stalls anywhere
fails the whole attempt within ``timeout_s``; ending the session (releasing what it holds)
then has at most `CLEANUP_S` more, so a caller hears back within ``timeout_s + CLEANUP_S``
(plus scheduling slack), never a worker forever.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from types import TracebackType
from typing import Protocol, Self

from app.vendors.tool import ToolData
from app.words import FrameKind, ProtocolName


@dataclass(frozen=True)
class Frame:
    """A frame: position in mm and rotation as a unit quaternion w, x, y, z."""

    position_mm: tuple[float, float, float]
    quaternion: tuple[float, float, float, float]


def finite_frame(frame: Frame) -> None:
    """ValueError when a position or quaternion value is not a finite number."""
    values = [*frame.position_mm, *frame.quaternion]
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"the frame holds a value that is not a finite number: {values}")


@dataclass(frozen=True)
class LiveTool:
    """The TCP the robot moves by right now, as its controller reports it (contract v1.3
    LiveTool): the tool number where the controller has one (its active tool) and the frame
    (that tool's data, or the one live TCP); both None where the controller does not say
    (its interface names no tool a program moves by)."""

    number: int | None
    frame: Frame | None


@dataclass(frozen=True)
class LiveFrame:
    """The frame the robot moves in right now, as its controller reports it (contract v1.4,
    "a robot's live base is named where the controller says"): its frame number, its name
    and its value in the robot's base frame, each None where the controller does not say
    (each connector's module says which it reads)."""

    number: int | None
    name: str | None
    frame: Frame | None


#: A controller that says nothing of the frame its robot moves in.
UNREAD_FRAME = LiveFrame(None, None, None)


@dataclass(frozen=True)
class PoseReading:
    """One read of where the robot stands: its flange in the robot's base frame (converted
    per protocol through app.kinematics.frames), its joints, the tool it moves by, the frame
    it moves in, and every value read, as the controller printed it (kept with a captured
    touch, for the audit). The live frame comes with the same read (the watcher reads every
    robot each interval: one read a robot, not two)."""

    flange: Frame
    joints_deg: tuple[float, ...] | None
    live_tool: LiveTool
    readings: dict[str, str]
    live_frame: LiveFrame = UNREAD_FRAME


@dataclass(frozen=True)
class ToolTarget:
    """Where a tool lives in the controller: a tool number (a protocol addressed BySlot, in
    its maker's tool_numbers), or a named symbol (BySymbol)."""

    slot: int | None = None  # the tool number, within the maker's tool_numbers
    symbol: str | None = None  # a RAPID "TASK/MODULE/SYMBOL", e.g. "T_ROB1/user/tTorch"


@dataclass(frozen=True)
class FrameTarget:
    """Where a frame lives in the controller, and what it is: a frame number, or a symbol
    ("TASK/MODULE/SYMBOL"), or neither (a frame named by its values), as the protocol's
    `WireProtocol.frames` says; `kind` "base" or "fixed_tool" (a connector writes what the
    controller keeps of it: a base's type, the data type of the symbol)."""

    kind: FrameKind = "base"
    slot: int | None = None
    symbol: str | None = None
    #: the frame's name, written where the controller keeps one beside the frame; None
    #: leaves the controller's name as it is
    name: str | None = None


@dataclass(frozen=True)
class ControllerSettings:
    """How to reach one robot's controller (the password only ever in memory, in clear).

    `port` is the port of a single-service protocol; a protocol of several services is
    reached on each service's port: `ports` where it names the service, else the service's
    default (the protocol's `WireProtocol.port_of`, app.vendors.maker), and its `port` is its
    main service's port."""

    protocol: ProtocolName
    host: str
    port: int
    username: str | None
    password: str | None
    timeout_s: float = 5.0
    tls_verify: bool = True
    ports: Mapping[str, int] = field(default_factory=dict, hash=False)

    def __repr__(self) -> str:
        # The password never reaches a log line or a traceback through a repr.
        secret = "set" if self.password else "none"
        return (
            f"ControllerSettings(protocol={self.protocol!r}, host={self.host!r}, "
            f"port={self.port}, ports={dict(self.ports)!r}, username={self.username!r}, "
            f"password=<{secret}>, timeout_s={self.timeout_s}, tls_verify={self.tls_verify})"
        )

    __str__ = __repr__


class ControllerError(Exception):
    """Whatever went wrong talking to a controller."""

    #: True once a write's bytes may have left for the controller: it may then hold the
    #: new frame or the old one, and only a later read can tell (set by `write_sent`).
    write_sent: bool = False


class ControllerUnreachable(ControllerError):
    """The controller could not be reached or stopped answering: refused, reset, timed out."""


class ControllerSilent(ControllerUnreachable):
    """Something accepted the TCP connection and sent nothing back in the time allowed: it
    listens at the port, but perhaps does not speak the protocol tried (another maker's
    controller, another service's port) or is hung."""


class ControllerRefused(ControllerError):
    """The controller answered and said no; `controller_message` is its own words, `remedy`
    what a person can do about it when the connector knows."""

    def __init__(self, message: str, *, controller_message: str, remedy: str | None = None) -> None:
        super().__init__(message if remedy is None else f"{message}; {remedy}")
        self.controller_message = controller_message
        self.remedy = remedy


class ControllerCredentialsRefused(ControllerRefused):
    """The controller refused the user name and password it was given (`user`)."""

    def __init__(self, message: str, *, controller_message: str, user: str) -> None:
        super().__init__(message, controller_message=controller_message)
        self.user = user


class ControllerProtocolError(ControllerError):
    """The controller answered something this connector cannot read (not the protocol)."""


class FrameWriterMissing(ControllerError):
    """No remote interface of this controller writes a frame (contract v1.4: 501
    /no-frame-writer): `reason` says why, in the vendor's documents' words where they have
    them, and `file` names the file a person loads by hand instead. Nothing was sent."""

    def __init__(self, reason: str, *, file: str) -> None:
        super().__init__(f"{reason}; load {file} by hand instead")
        self.reason = reason
        self.file = file


class Connector(Protocol):
    """One controller session: read and write tool frames, read the robot's pose. Use it as
    a context manager."""

    protocol: str

    def describe(self, target: ToolTarget) -> str:
        """The target as the controller names it: "$TOOL_DATA[3]", "UTOOL[3]", "T_ROB1/user/t"."""
        ...

    def read_tool(self, target: ToolTarget) -> ToolData:
        """The tool frame (and load, where the controller keeps one) the controller holds."""
        ...

    def write_tool(self, target: ToolTarget, data: ToolData) -> None:
        """Write the tool frame (and the load when `data.load` is set) into the controller."""
        ...

    def read_pose(self) -> PoseReading:
        """Where the robot stands: its flange in the robot's base frame, its joints, the tool
        it moves by, the frame it moves in (`live_frame`) and every value read as the
        controller printed it (contract v1.3, v1.4)."""
        ...

    def describe_frame(self, target: FrameTarget) -> str:
        """The frame as the controller names it (`WireProtocol.describe_frame`); ValueError
        saying what to set when it cannot address one."""
        ...

    def read_frame(self, target: FrameTarget) -> Frame:
        """The frame the controller holds, in the robot's base frame; FrameWriterMissing
        where the controller keeps frames no remote interface reads."""
        ...

    def write_frame(self, target: FrameTarget, frame: Frame) -> None:
        """Write the frame (a pose in the robot's base frame) into the controller;
        FrameWriterMissing (nothing sent) where no remote interface writes one."""
        ...

    def close(self) -> None:
        """End the session; never raises."""
        ...

    def __enter__(self) -> Connector: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


class ClosingSession:
    """The context-manager half of a Connector, written once: `with` closes the session."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class FramesByHand:
    """The frame half of a Connector for a controller no remote interface of which writes or
    reads a frame: after `describe_frame` checked the target, `read_frame` and `write_frame`
    raise FrameWriterMissing with the class's `frame_reason` and `frame_file`, sending
    nothing."""

    frame_reason: str
    frame_file: str

    def describe_frame(self, target: FrameTarget) -> str:
        raise NotImplementedError

    def read_frame(self, target: FrameTarget) -> Frame:
        """FrameWriterMissing: no remote interface serves the frame."""
        self.describe_frame(target)
        raise FrameWriterMissing(self.frame_reason, file=self.frame_file)

    def write_frame(self, target: FrameTarget, frame: Frame) -> None:
        """FrameWriterMissing, nothing sent: no remote interface writes the frame."""
        self.describe_frame(target)
        raise FrameWriterMissing(self.frame_reason, file=self.frame_file)


@contextmanager
def write_sent() -> Iterator[None]:
    """Wrap a write from the moment its bytes are handed to the socket: a ControllerError
    raised inside says the controller may hold the new value (`write_sent`)."""
    try:
        yield
    except ControllerError as exc:
        exc.write_sent = True
        raise


#: What ending a session may take past its deadline: releasing edit mastership, a logout, a
#: disconnect call. Short, because the caller is waiting for the answer.
CLEANUP_S = 0.5


class Deadline:
    """One time budget for a whole session: each wait gets what is left of it."""

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self._end = time.monotonic() + timeout_s
        #: Whether the controller has sent anything under this budget (app.vendors.sockets
        #: sets it): a stall before it is `ControllerSilent`, after it one that stopped.
        self.answered = False

    def extended(self, seconds: float) -> Deadline:
        """A deadline `seconds` after this one (what ending the session may use)."""
        later = Deadline(self.timeout_s + seconds)
        later._end = self._end + seconds
        later.answered = self.answered
        return later

    def left(self) -> float:
        """Seconds left, 0 once spent (never raises)."""
        return max(0.0, self._end - time.monotonic())

    def remaining(self) -> float:
        """Seconds left; raises ControllerUnreachable once the budget is spent."""
        left = self._end - time.monotonic()
        if left <= 0:
            raise ControllerUnreachable(
                f"the controller did not answer within {self.timeout_s:g} s"
            )
        return left
