"""What every controller connector offers, and the data it reads and writes.

A connector reads and writes one tool's frame (the TCP: where the tool's working point is
and how it is oriented in the flange frame) in a robot controller, over the controller's
own wire protocol. No database and no HTTP framework here: the service that deploys or
reconciles runs a connector in a worker thread and owns everything else.

Every connector converts through `app.kinematics.poses` (scipy Rotation), so the values a
controller holds in its own convention (KUKA A B C, FANUC W P R, ABB quaternion) and the
quaternion tcpcal holds are one rotation. A session keeps to one deadline (`Deadline`),
started when it is opened (`connect(settings)`) and shared by every wait after it: connect,
login, mastership, each read and write, the read-back. A controller that stalls anywhere
fails the whole attempt within ``timeout_s``; ending the session (releasing what it holds)
then has at most `CLEANUP_S` more, so a caller hears back within ``timeout_s + CLEANUP_S``
(plus scheduling slack), never a worker forever.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from types import TracebackType
from typing import Literal, Protocol, Self, get_args

from app.tool_numbers import TOOL_NUMBERS
from app.words import DeploymentScope

ProtocolName = Literal[
    "kuka_kvp",
    "fanuc_rmi",
    "abb_rws1",
    "abb_rws2",
    "techman",
    "yaskawa_hses",
    "ur_rtde",
]
PROTOCOLS: tuple[str, ...] = get_args(ProtocolName)

#: The port each single-service protocol listens on unless the plant changed it (`port`).
DEFAULT_PORTS: dict[str, int] = {
    "kuka_kvp": 7000,  # KUKAVARPROXY
    "fanuc_rmi": 16001,  # Remote Motion Interface, FRC_Connect
    "abb_rws1": 80,  # RobotWare 6 Robot Web Services, HTTP + Digest
    "abb_rws2": 443,  # RobotWare 7 Robot Web Services 2.0, HTTPS + Basic
}

#: The services of each protocol that talks over several ports, each with the port it
#: listens on unless the plant changed it (`ports`, contract v1.3), the first the main one.
SERVICE_PORTS: dict[str, dict[str, int]] = {
    # TMflow: Listen Node (TCP, ChangeTCP) and Ethernet Slave (TCP, the data table)
    "techman": {"listen_node": 5890, "ethernet_slave": 5891},
    # High Speed Ethernet Server: robot control (UDP) and file control (UDP)
    "yaskawa_hses": {"robot": 10040, "file": 10041},
    # RTDE (TCP) and the secondary client interface (TCP, URScript)
    "ur_rtde": {"rtde": 30004, "secondary": 30002},
}

#: Tool numbers each slot-addressed protocol accepts, inclusive (the exports' ranges).
SLOT_RANGES: dict[str, tuple[int, int]] = {
    "kuka_kvp": TOOL_NUMBERS["kuka"],  # $TOOL_DATA[1..16] in $config.dat
    "fanuc_rmi": TOOL_NUMBERS["fanuc"],  # UTOOL[1..10]
    "yaskawa_hses": TOOL_NUMBERS["yaskawa"],  # TOOL.CND tools 0..63 (YRC1000, DX200)
}

#: How each slot-addressed protocol names tool number n.
SLOT_NAMES: dict[str, str] = {
    "kuka_kvp": "$TOOL_DATA[{}]",
    "fanuc_rmi": "UTOOL[{}]",
    "yaskawa_hses": "TOOL.CND tool {}",
}

#: Which field of a tool names its place in the controller, per protocol: "slot" (a tool
#: number), "symbol" (ABB "TASK/MODULE/SYMBOL"; the tool's `controller_symbol`) or "live"
#: (the robot's one live TCP, written by value: Techman ChangeTCP, UR set_tcp; contract
#: v1.3 "a Techman or UR tool is named on the controller by values (no slot)").
TARGET_FIELD: dict[str, Literal["slot", "symbol", "live"]] = {
    "kuka_kvp": "slot",
    "fanuc_rmi": "slot",
    "abb_rws1": "symbol",
    "abb_rws2": "symbol",
    "techman": "live",
    "yaskawa_hses": "slot",
    "ur_rtde": "live",
}

#: How a live-TCP protocol names the one TCP every tool of the robot is written to.
LIVE_TARGETS: dict[str, str] = {"techman": "current TCP", "ur_rtde": "tcp_offset"}

#: Where a deployment under each protocol holds (contract v1.3 Deployment `scope`):
#: "stored" where the controller keeps it, "live" where it holds only for the running
#: program (the next program start sets its own TCP).
SCOPES: dict[str, DeploymentScope] = {
    "kuka_kvp": "stored",  # $TOOL_DATA in $config.dat
    "fanuc_rmi": "stored",  # UTOOL, a system variable
    "abb_rws1": "stored",  # a PERS tooldata
    "abb_rws2": "stored",
    "techman": "live",  # ChangeTCP: the running project's current TCP
    "yaskawa_hses": "stored",  # TOOL.CND
    "ur_rtde": "live",  # set_tcp: the running program's TCP
}


def scope_of(protocol: str) -> DeploymentScope:
    """Where a deployment under `protocol` holds; "stored" for a protocol not known here."""
    return SCOPES.get(protocol, "stored")


# RAPID identifiers: a letter, then letters, digits or underscores, at most 32 characters
# (ABB Technical reference manual - RAPID overview, "Identifiers").
_RAPID_IDENTIFIER = r"[A-Za-z][A-Za-z0-9_]{0,31}"
ABB_SYMBOL_PATTERN = re.compile(
    rf"^({_RAPID_IDENTIFIER})/({_RAPID_IDENTIFIER})/({_RAPID_IDENTIFIER})$"
)


@dataclass(frozen=True)
class ToolLoad:
    """The tool's mass and the position of its centre of gravity in the flange frame."""

    mass_kg: float
    cog_mm: tuple[float, float, float]


@dataclass(frozen=True)
class ToolData:
    """A tool frame in the flange frame: position in mm, rotation as a unit quaternion."""

    position_mm: tuple[float, float, float]
    quaternion: tuple[float, float, float, float]  # w, x, y, z: tool frame in the flange frame
    load: ToolLoad | None = None


@dataclass(frozen=True)
class Frame:
    """A frame: position in mm and rotation as a unit quaternion w, x, y, z."""

    position_mm: tuple[float, float, float]
    quaternion: tuple[float, float, float, float]


@dataclass(frozen=True)
class LiveTool:
    """The TCP the robot moves by right now, as its controller reports it (contract v1.3
    LiveTool): the tool number where the controller has one (KUKA $ACT_TOOL, FANUC's active
    UTOOL, Yaskawa's reported tool) and the frame (KUKA $TOOL, FANUC UTOOL[n], UR
    tcp_offset, Techman's current TCP); both None where the controller does not say (ABB:
    RWS does not say which tooldata a program moves by)."""

    number: int | None
    frame: Frame | None


@dataclass(frozen=True)
class PoseReading:
    """One read of where the robot stands: its flange in the robot's base frame (converted
    per protocol through app.kinematics.frames), its joints, the tool it moves by, and every
    value read, as the controller printed it (kept with a captured touch, for the audit)."""

    flange: Frame
    joints_deg: tuple[float, ...] | None
    live_tool: LiveTool
    readings: dict[str, str]


@dataclass(frozen=True)
class ToolTarget:
    """Where a tool lives in the controller: a tool number, or an ABB RAPID symbol."""

    slot: int | None = None  # KUKA $TOOL_DATA[slot] 1-16, FANUC UTOOL[slot] 1-10
    symbol: str | None = None  # ABB "TASK/MODULE/SYMBOL", e.g. "T_ROB1/user/tTorch"


@dataclass(frozen=True)
class ControllerSettings:
    """How to reach one robot's controller (the password only ever in memory, in clear).

    `port` is the port of a single-service protocol; a protocol of several services
    (SERVICE_PORTS) is reached on `port_of(service)`: `ports` where it names the service,
    else the service's default, and its `port` is its main service's port (what `where`
    names)."""

    protocol: ProtocolName
    host: str
    port: int
    username: str | None
    password: str | None
    timeout_s: float = 5.0
    tls_verify: bool = True
    ports: Mapping[str, int] = field(default_factory=dict, hash=False)

    def port_of(self, service: str) -> int:
        """The port of one of the protocol's services; ValueError naming the services."""
        services = SERVICE_PORTS.get(self.protocol, {})
        if service not in services:
            known = ", ".join(services) or "none: it has one port, `port`"
            raise ValueError(f"{self.protocol} has no service {service!r}; its services: {known}")
        return self.ports.get(service, services[service])

    def ports_in_use(self) -> dict[str, int]:
        """Every service's port (empty for a single-service protocol)."""
        return {name: self.port_of(name) for name in SERVICE_PORTS.get(self.protocol, {})}

    def where(self) -> str:
        """The controller's address as a message names it: "10.0.0.7:7000", or for a
        protocol of several services "10.0.0.7 (listen_node 5890, ethernet_slave 5891)"."""
        ports = self.ports_in_use()
        if not ports:
            return f"{self.host}:{self.port}"
        return f"{self.host} ({', '.join(f'{name} {port}' for name, port in ports.items())})"

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
        it moves by and every value read as the controller printed it (contract v1.3)."""
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


def target_problem(protocol: str, target: ToolTarget) -> str | None:
    """Why `target` cannot address a tool under `protocol`, in a sentence; None when it can."""
    field = TARGET_FIELD.get(protocol)
    if field is None:
        return f"unknown controller protocol {protocol!r}; known: {', '.join(PROTOCOLS)}"
    if field == "slot":
        low, high = SLOT_RANGES[protocol]
        if target.slot is None:
            return (
                f"a {protocol} controller addresses tools by number: "
                f"set the tool's slot ({low}-{high})"
            )
        if not low <= target.slot <= high:
            return (
                f"slot {target.slot} is outside {low}-{high}, "
                f"the tool numbers of a {protocol} controller"
            )
        return None
    if field == "live":
        return None  # any tool: written by its values into the robot's one live TCP
    if target.symbol is None:
        return (
            f"an {protocol} controller addresses tools by RAPID symbol: set the tool's "
            'controller_symbol as "TASK/MODULE/SYMBOL", e.g. "T_ROB1/user/tTorch"'
        )
    return abb_symbol_problem(target.symbol)


def describe_target(protocol: str, target: ToolTarget) -> str:
    """The target as the controller names it: "$TOOL_DATA[3]", "UTOOL[3]", "T_ROB1/user/t";
    ValueError saying what to set when `target` cannot address a tool under `protocol`."""
    check_target(protocol, target)
    if TARGET_FIELD[protocol] == "slot":
        return SLOT_NAMES[protocol].format(target.slot)
    if TARGET_FIELD[protocol] == "live":
        return LIVE_TARGETS[protocol]
    return str(target.symbol)


def abb_symbol_problem(symbol: str) -> str | None:
    """Why `symbol` is not a "TASK/MODULE/SYMBOL" RAPID path, in a sentence; None when it is."""
    if ABB_SYMBOL_PATTERN.match(symbol) is None:
        return (
            f'{symbol!r} is not "TASK/MODULE/SYMBOL" (three RAPID names of a letter then '
            'letters, digits or _, at most 32 characters each), e.g. "T_ROB1/user/tTorch"'
        )
    return None


def split_abb_symbol(symbol: str) -> tuple[str, str, str]:
    """ "T_ROB1/user/tTorch" -> ("T_ROB1", "user", "tTorch"); ValueError naming the problem."""
    match = ABB_SYMBOL_PATTERN.match(symbol)
    if match is None:
        raise ValueError(abb_symbol_problem(symbol))
    task, module, name = match.groups()
    return task, module, name


def check_target(protocol: str, target: ToolTarget) -> None:
    """ValueError saying what to set when `target` cannot address a tool under `protocol`."""
    problem = target_problem(protocol, target)
    if problem is not None:
        raise ValueError(problem)


@contextmanager
def write_sent() -> Iterator[None]:
    """Wrap a write from the moment its bytes are handed to the socket: a ControllerError
    raised inside says the controller may hold the new value (`write_sent`)."""
    try:
        yield
    except ControllerError as exc:
        exc.write_sent = True
        raise


#: What ending a session may take past its deadline: releasing ABB edit mastership, the RWS
#: logout, FANUC's FRC_Disconnect. Short, because the caller is waiting for the answer.
CLEANUP_S = 0.5


class Deadline:
    """One time budget for a whole session: each wait gets what is left of it."""

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self._end = time.monotonic() + timeout_s

    def extended(self, seconds: float) -> Deadline:
        """A deadline `seconds` after this one (what ending the session may use)."""
        later = Deadline(self.timeout_s + seconds)
        later._end = self._end + seconds
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


def finite_tool_data(data: ToolData) -> None:
    """ValueError when a position, quaternion or load value is not a finite number."""
    values = [*data.position_mm, *data.quaternion]
    if data.load is not None:
        values += [data.load.mass_kg, *data.load.cog_mm]
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"tool data holds a value that is not a finite number: {values}")
