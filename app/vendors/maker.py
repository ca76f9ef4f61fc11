"""What a controller maker's package declares, as one `Maker` in its ``__init__``: the words
it answers to, its text and its file, its tool numbers, and the wire protocols its
controllers speak. app.vendors.registry lists the makers; tests/vendors/test_registry.py
holds that each provides all of it.

The text, the file and the connectors are reached through small loader functions, so that
importing a maker's package (and so the registry, the API schemas) loads neither scipy nor a
protocol's client: a module is imported the first time it is used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, Protocol

from app.arrays import FloatArray
from app.kinematics.dh_table import Kinematics
from app.vendors.connector import Connector, ControllerSettings, FrameTarget, ToolTarget
from app.vendors.files import ControllerFile, FileContext, FileTool, ParsedTool
from app.vendors.frame import FileFrame, FrameData, ParsedFrame
from app.vendors.text import ControllerExport
from app.vendors.tool import ToolData
from app.words import DeploymentScope, PoseFormat, WorkingAxis


class TextModule(Protocol):
    """A maker's ``text`` module: the tool's one line of controller text, and its reader."""

    def export(self, tool: ToolData) -> ControllerExport:
        """The tool's TCP (and load where the controller stores it) as the maker's text."""
        ...

    def parse(self, text: str) -> tuple[FloatArray, FloatArray]:
        """The text -> (position (3,) mm, quaternion w, x, y, z (4,))."""
        ...


class FileModule(Protocol):
    """A maker's ``file`` module: the file its controller loads, and its reader."""

    def write(self, tools: list[FileTool], context: FileContext) -> ControllerFile:
        """The file for one tool, or (context.table) for a robot's tools."""
        ...

    def read(self, text: str) -> list[ParsedTool]:
        """Every tool of such a file (as `write` writes it, or the controller saves it)."""
        ...


class FrameModule(Protocol):
    """A maker's ``frame`` module: a frame (a base, a fixed tool) as its text and as the file
    its controller loads, and their readers."""

    def export(self, frame: FrameData) -> ControllerExport:
        """The frame as the maker's text."""
        ...

    def parse(self, text: str) -> tuple[FloatArray, FloatArray]:
        """The text -> (position (3,) mm, quaternion w, x, y, z (4,))."""
        ...

    def write(self, frames: list[FileFrame], context: FileContext) -> ControllerFile:
        """The file for one frame, or (context.table) for a robot's frames."""
        ...

    def read(self, text: str) -> list[ParsedFrame]:
        """Every frame of such a file (as `write` writes it, or the controller saves it)."""
        ...


#: A connector class: called with the settings, it opens a session.
OpenSession = Callable[[ControllerSettings], Connector]


@dataclass(frozen=True)
class BySlot:
    """Tools addressed by number: `numbers` (first, last, inclusive), and how the controller
    names number n (`name`, e.g. "$TOOL_DATA[{}]")."""

    numbers: tuple[int, int]
    name: str


@dataclass(frozen=True)
class BySymbol:
    """Tools addressed by a name the tool keeps as its ``controller_symbol``: `how` finishes
    the sentence "a ... controller addresses tools by", `problem` says why a symbol is not one
    (None when it is)."""

    how: str
    problem: Callable[[str], str | None]


@dataclass(frozen=True)
class LiveTcp:
    """Every tool written by its values into the robot's one live TCP (a script's or a
    command's set TCP; contract v1.3: such a tool "is named on the controller by values (no
    slot)"): `name` is how the controller names that TCP ("tcp_offset")."""

    name: str


@dataclass(frozen=True)
class ByValue:
    """Frames named by their values, not by a number (contract v1.4, "Frames": a frame
    named by values, no slot): `name` is how the controller names the frame it holds
    ("current base"), `live` True where writing it changes the running program's frame
    only (scope live)."""

    name: str
    live: bool


#: How a protocol addresses a robot's frames.
FrameAddress = BySlot | BySymbol | ByValue


@dataclass(frozen=True)
class WireProtocol:
    """A protocol a maker's controllers speak: its name (``controller.protocol``), how it
    addresses a tool, its connector (None until this tcpcal has one: the connection is
    stored, and nothing is sent), and where it listens unless the plant changed it: one
    `default_port`, or (`services`) each of its services' ports, the first the main one
    (contract v1.3 ``ports``); `udp` when they are UDP ports, not TCP."""

    name: str
    address: BySlot | BySymbol | LiveTcp
    connector: Callable[[], OpenSession] | None
    default_port: int | None = None
    services: tuple[tuple[str, int], ...] = ()
    udp: bool = False
    #: how it addresses a robot's frames (contract v1.4 "Frames"): frame numbers and their
    #: names, symbols, or values
    frames: FrameAddress | None = None
    #: when its controller refuses a pose read (ControllerRefused), as an example finishing
    #: "a <maker> ..." ("in `$IPO_MODE #TCP`"); None to give no example
    refused_when: str | None = None
    #: what the controller settings' `username` is to it ("the RWS user"), and who it logs
    #: in as when none is set, in words (its maker's factory user); None: it takes no user
    user: str | None = None
    default_user: str | None = None
    #: why its controller does not say which tool the robot moves by (a pose read's live
    #: tool has no number and no frame), in words ("RWS does not say which tooldata a
    #: program uses"); None when it says
    live_tool_unsaid: str | None = None

    @property
    def target_field(self) -> Literal["slot", "symbol", "live"]:
        """Which field of a tool names its place: "slot" (a tool number), "symbol", or
        "live" (none: the robot's one live TCP)."""
        if isinstance(self.address, BySlot):
            return "slot"
        return "symbol" if isinstance(self.address, BySymbol) else "live"

    @property
    def scope(self) -> DeploymentScope:
        """Where a deployment holds (contract v1.3 Deployment `scope`): "live" where it is
        written into the robot's one live TCP, which holds only for the running program (the
        next program start sets its own), "stored" where the controller keeps it."""
        return "live" if isinstance(self.address, LiveTcp) else "stored"

    @property
    def service_ports(self) -> dict[str, int]:
        """Each service's default port ({} for a protocol of one port)."""
        return dict(self.services)

    def port_of(self, settings: ControllerSettings, service: str) -> int:
        """The port of one of the protocol's services; ValueError naming the services."""
        defaults = self.service_ports
        if service not in defaults:
            known = ", ".join(defaults) or "none: it has one port, `port`"
            raise ValueError(f"{self.name} has no service {service!r}; its services: {known}")
        return settings.ports.get(service, defaults[service])

    def ports_in_use(self, settings: ControllerSettings) -> dict[str, int]:
        """Every service's port (empty for a single-service protocol)."""
        return {name: self.port_of(settings, name) for name in self.service_ports}

    def where(self, settings: ControllerSettings) -> str:
        """The controller's address as a message names it: "10.0.0.7:7000", or for a
        protocol of several services "10.0.0.7 (listen_node 5890, ethernet_slave 5891)"."""
        ports = self.ports_in_use(settings)
        if not ports:
            return f"{settings.host}:{settings.port}"
        named = ", ".join(f"{name} {port}" for name, port in ports.items())
        return f"{settings.host} ({named})"

    def target_problem(self, target: ToolTarget) -> str | None:
        """Why `target` cannot address a tool here, in a sentence; None when it can."""
        if isinstance(self.address, LiveTcp):
            return None  # any tool: written by its values into the robot's one live TCP
        return self._place_problem(self.address, target.slot, target.symbol, "tool")

    def _place_problem(
        self,
        address: BySlot | BySymbol,
        slot: int | None,
        symbol: str | None,
        what: str,
        *,
        given_only: bool = False,
    ) -> str | None:
        """Why a `what` (tool, frame) at `slot` or `symbol` has no place at `address`;
        `given_only` checks only what is given (a frame registered may leave its slot or
        symbol for later: the deployment asks for it)."""
        if isinstance(address, BySymbol):
            if symbol is not None:
                return address.problem(symbol)
            if given_only:
                return None
            return f"an {self.name} controller addresses {what}s by {address.how}"
        low, high = address.numbers
        if slot is None:
            if given_only:
                return None
            return (
                f"a {self.name} controller addresses {what}s by number: "
                f"set the {what}'s slot ({low}-{high})"
            )
        if not low <= slot <= high:
            return (
                f"slot {slot} is outside {low}-{high}, the {what} numbers of a {self.name} "
                f"controller ({address.name.format(f'{low}..{high}')}): "
                f"give a slot from {low} to {high}"
            )
        return None

    @property
    def frame_scope(self) -> DeploymentScope:
        """Where a frame deployment holds: "live" where the frame is written into the running
        program's, "stored" where the controller keeps it."""
        return "live" if isinstance(self.frames, ByValue) and self.frames.live else "stored"

    def frame_problem(self, target: FrameTarget, *, given_only: bool = False) -> str | None:
        """Why `target` cannot address a frame here, in a sentence; None when it can. The one
        check of a frame's place: at deployment (the connector's `describe_frame`), and with
        `given_only` when a frame is registered on a robot of this protocol's maker (only its
        slot or symbol as given: app.vendors.registry.vendor_frame_problem)."""
        address = self.frames
        if address is None:
            if given_only:
                return None
            return f"a {self.name} controller has no frames tcpcal can address"
        if isinstance(address, ByValue):
            return None  # named by its values: any frame
        return self._place_problem(
            address, target.slot, target.symbol, "frame", given_only=given_only
        )

    def describe_frame(self, target: FrameTarget) -> str:
        """The frame as the controller names it: "BASE_DATA[3]", a symbol, "current base";
        ValueError saying what to set when it cannot address one."""
        problem = self.frame_problem(target)
        if problem is not None:
            raise ValueError(problem)
        address = self.frames
        if isinstance(address, BySlot):
            return address.name.format(target.slot)
        if isinstance(address, ByValue):
            return address.name
        return str(target.symbol)

    def check(self, target: ToolTarget) -> None:
        """ValueError saying what to set when `target` cannot address a tool here."""
        problem = self.target_problem(target)
        if problem is not None:
            raise ValueError(problem)

    def describe(self, target: ToolTarget) -> str:
        """The target as the controller names it: "$TOOL_DATA[3]", "UTOOL[3]",
        "T_ROB1/user/t"; ValueError saying what to set when it cannot address a tool."""
        self.check(target)
        if isinstance(self.address, BySlot):
            return self.address.name.format(target.slot)
        if isinstance(self.address, LiveTcp):
            return self.address.name
        return str(target.symbol)


@dataclass(frozen=True)
class Maker:
    """One controller maker, as its package declares it (``MAKER``).

    - `format`: its controller format (``?format=``), a word of app.words.ControllerFormat;
    - `pose_format`: the pose format its pendant shows a flange pose in ("kuka_abc"): what a
      touch captured from its controllers is typed in unless the person says otherwise;
    - `name`: how a sentence names it (the maker as its own documents spell it);
    - `vendor_words`: what a robot's vendor contains when it is this maker's ("motoman"), and
      `vendor_initials`: whole words that name it alone ("ur", "tm");
    - `file_kind`: what its file is, in a few words (the console's download buttons);
    - `tool_numbers`: (first, last) when its controllers number their tools, else None;
    - `text`, `file`: its text and file modules; `protocols`: what its connectors speak,
      each with how it addresses a tool and a frame (`WireProtocol.frames`, the one
      declaration of a frame's place, checked at registration and at deployment);
    - `arms`: the nominal kinematics of its arms, each named by the preset the API accepts
      (`{"preset": "ur5e"}`; app.vendors.registry.PRESETS): the controller's flange frame,
      with an all-zero tool, in its base frame. Nominal means as designed: a real arm's
      factory calibration differs by up to a few tenths of a millimetre, which is why a
      robot may carry its own DH links instead of a preset.
    """

    format: str
    pose_format: PoseFormat
    name: str
    vendor_words: tuple[str, ...]
    file_kind: str
    tool_numbers: tuple[int, int] | None
    text: Callable[[], TextModule]
    file: Callable[[], FileModule]
    #: its frame module: a frame's text and file (contract v1.4 "Frame touches and methods")
    frame: Callable[[], FrameModule]
    protocols: tuple[WireProtocol, ...] = ()
    vendor_initials: tuple[str, ...] = ()
    arms: tuple[Kinematics, ...] = ()
    #: how a sentence names the number of the tool its controller reports the robot moves by,
    #: its name and its controller's word ("<maker> $ACT_TOOL"); None where its controller
    #: reports no tool number
    active_tool: str | None = None
    #: how a sentence names the bare flange (no tool selected) in its controller's words, its
    #: name with them: its null tool ("<maker> $NULLFRAME"), or for a maker of one live TCP
    #: that TCP, the bare flange being its zero ("<maker> tcp_offset"); None where it has no
    #: word of its own (its tool 0, or it does not say)
    bare_flange: str | None = None
    #: the tool axis its pendant's orientation methods take as the working axis ("x"),
    #: where the maker has one of its own
    working_axis: WorkingAxis | None = None
    #: the tool calibration methods its pendant teaches, each (the method's word, as
    #: `app.words.word` reads it off the method's Literal; the pendant's name for it,
    #: "ABC 2-point"): GET /v1/methods' description of the method names them
    teaches: tuple[tuple[str, str], ...] = ()
