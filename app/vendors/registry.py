"""The controller makers tcpcal serves, and what the rest of tcpcal asks of them.

Each maker is one package under app/vendors/ declaring its `Maker` (app.vendors.maker): its
format and text, its file, its tool numbers, the protocols its connectors speak. This module
lists them and answers by format (`export_tool`, `parse_controller_text`, `controller_file`,
`parse_controller_file`, and a frame's `export_frame`, `parse_frame_text`, `frame_file`,
`parse_frame_file`), by robot vendor (`vendor_formats`, `vendor_protocols`) and by
protocol (`connect`, `has_connector`, `frame_writer_missing`, `pose_format_of`,
`target_problem`, `describe_target`, `where`, `DEFAULT_PORTS`, `SERVICE_PORTS`,
`SLOT_RANGES`, `TARGET_FIELD`), and the arms they publish by preset name (`PRESETS`).

| protocol | connector | vendor document followed |
|---|---|---|
| kuka_kvp | kuka/kvp.py | KUKAVARPROXY / OpenShowVar (ImtsSrl/KUKAVARPROXY README) |
| fanuc_rmi | fanuc/rmi.py | FANUC B-84184EN Remote Motion Interface Operator's Manual |
| abb_rws1 | abb/rws.py | ABB Robot Web Services 1.0 (RobotWare 6) |
| abb_rws2 | abb/rws.py | ABB Robot Web Services 2.0 (RobotWare 7) |
| techman | techman/tmflow.py | Techman Listen Node manual (I848); TMflow Ethernet Slave table |
| yaskawa_hses | yaskawa/hses.py | Yaskawa High-Speed Ethernet Server Function (FS100 160766-1CD) |
| ur_rtde | ur/rtde.py | UR RTDE Guide (30004) and the secondary client interface (30002) |

Every protocol has its connector today; a controller of a protocol whose connector is not
written yet (the table's "(not yet)") would be stored, and nothing sent to it
(app.services.robots.connection.settings_of answers 501 /no-connector).
tests/vendors/test_registry.py holds the table true to the registry.

Adding a maker: its package, its line in `MAKERS`, and its words (format, protocols) in
app.words; tests/vendors/test_registry.py holds that it provides all the registry
asks. Importing this module imports the makers' declarations only (their arms' DH tables
among them, plain dataclasses): a text, a file or a connector module is loaded when first
used (no scipy, no protocol client before; tests/vendors/test_registry.py holds it). Each
connector's read or write has its own deadline of ``timeout_s`` covering all its network
waits; a session whose controller stopped answering closes without waiting again. The
simulators the tests drive are in tests/controllers/.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from typing import Literal

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.kinematics.dh_table import Kinematics
from app.vendors import abb, fanuc, kuka, techman, ur, yaskawa
from app.vendors.connector import (
    Connector,
    ControllerSettings,
    FramesByHand,
    FrameTarget,
    FrameWriterMissing,
    ToolTarget,
)
from app.vendors.files import ControllerFile, FileContext, FileTool, ParsedTool
from app.vendors.frame import FileFrame, FrameData, ParsedFrame
from app.vendors.maker import BySlot, Maker, WireProtocol
from app.vendors.text import ControllerExport
from app.vendors.tool import ToolData
from app.words import CONTROLLER_FORMATS, PROTOCOLS, DeploymentScope, PoseFormat

#: Every maker, in the order the API lists their formats.
MAKERS: tuple[Maker, ...] = (
    kuka.MAKER,
    abb.MAKER,
    fanuc.MAKER,
    ur.MAKER,
    yaskawa.MAKER,
    techman.MAKER,
)


def _in_order(names: Iterable[str], order: Sequence[str]) -> list[str]:
    """`names` in the order of `order` (app.words' Literals), any other name last."""
    return sorted(names, key=lambda name: order.index(name) if name in order else len(order))


#: The makers by controller format.
BY_FORMAT: dict[str, Maker] = {m.format: m for m in MAKERS}
_WIRES = {wire.name: wire for m in MAKERS for wire in m.protocols}
#: The wire protocols by name, in ProtocolName's order.
WIRE_PROTOCOLS: dict[str, WireProtocol] = {n: _WIRES[n] for n in _in_order(_WIRES, PROTOCOLS)}

#: The port each single-service protocol listens on unless the plant changed it (`port`).
DEFAULT_PORTS: dict[str, int] = {
    n: w.default_port for n, w in WIRE_PROTOCOLS.items() if w.default_port is not None
}
#: The services of each protocol that talks over several ports, each with the port it
#: listens on unless the plant changed it (`ports`, contract v1.3), the first the main one.
SERVICE_PORTS: dict[str, dict[str, int]] = {
    n: w.service_ports for n, w in WIRE_PROTOCOLS.items() if w.services
}
#: Where a deployment under each protocol holds: "stored" where the controller keeps it,
#: "live" where it holds only for the running program (contract v1.3 Deployment `scope`).
DEPLOYMENT_SCOPES: dict[str, DeploymentScope] = {n: w.scope for n, w in WIRE_PROTOCOLS.items()}
#: The makers whose protocols deploy in each scope, as a sentence names them ("A, B"; "A or
#: B"): the schemas' descriptions of `scope` and `not_live`.
_LIVE = tuple(m.name for m in MAKERS if any(w.scope == "live" for w in m.protocols))
LIVE_MAKERS, LIVE_MAKER_OR = ", ".join(_LIVE), " or ".join(_LIVE)
STORED_MAKERS = ", ".join(m.name for m in MAKERS if any(w.scope == "stored" for w in m.protocols))
#: The makers whose controllers address a tool by a symbol (`controller_symbol`), as a
#: sentence names them: the schemas' description of the field.
SYMBOL_MAKERS = ", ".join(
    m.name for m in MAKERS if any(w.target_field == "symbol" for w in m.protocols)
)
#: What makes a controller refuse a pose read, e.g. "a KUKA in `$IPO_MODE #TCP`" (each
#: protocol's `refused_when`): GET /v1/robots/{robot_id}/controller/pose's description.
REFUSAL_EXAMPLES = " or ".join(
    dict.fromkeys(
        f"a {m.name} {w.refused_when}" for m in MAKERS for w in m.protocols if w.refused_when
    )
)
#: The makers whose pendants take X as a tool's working axis (each maker's `working_axis`):
#: the glossary's `working_axis`.
X_AXIS_MAKERS = ", ".join(m.name for m in MAKERS if m.working_axis == "x")
#: What `username` is to each maker whose protocols take one, "ABB: the RWS user" (each
#: protocol's `user`): the controller's description of `username`; with whom it logs in as
#: when none is set (`default_user`), the description of the `username` sent.
_USERS = [(m.name, w) for m in MAKERS for w in m.protocols if w.user is not None]
USERNAMES = "; ".join(dict.fromkeys(f"{name}: {w.user}" for name, w in _USERS))
USERNAMES_SENT = "; ".join(
    dict.fromkeys(
        f"{name}: {w.user}" + (f" (default: {w.default_user})" if w.default_user else "")
        for name, w in _USERS
    )
)
#: The makers whose controllers do not say which tool the robot moves by ("ABB"), and why,
#: "ABB: RWS does not say ..." (each protocol's `live_tool_unsaid`): the schemas'
#: descriptions of a live tool read (Reconciliation.live_tool, LiveToolOut, FleetLive.state).
_UNSAID = [(m.name, w.live_tool_unsaid) for m in MAKERS for w in m.protocols if w.live_tool_unsaid]
LIVE_TOOL_UNSAID = ", ".join(dict.fromkeys(name for name, _ in _UNSAID))
LIVE_TOOL_UNSAID_WHY = "; ".join(dict.fromkeys(f"{name}: {why}" for name, why in _UNSAID))
#: The tool numbers the controllers report the robot moves by, as a sentence names them
#: ("KUKA $ACT_TOOL, ..."; each maker's `active_tool`): LiveToolOut.number's and
#: FleetLive.number's descriptions.
ACTIVE_TOOLS = ", ".join(m.active_tool for m in MAKERS if m.active_tool)


def taught_as(method: str) -> str:
    """How the pendants that teach a tool calibration method name it, "ABB TCP&Z,X; Fanuc
    six-point" (each maker's `teaches`, in MAKERS' order): the method's description in GET
    /v1/methods (app.methods). KeyError for a method no maker declares."""
    names = [f"{m.name} {name}" for m in MAKERS for taught, name in m.teaches if taught == method]
    if not names:
        raise KeyError(f"no maker declares that its pendant teaches {method!r}")
    return "; ".join(names)


def _bare_flanges() -> str:
    """The bare flange, no tool selected, as the controllers say it: a controller's tool 0
    (app.services.robots.live_tool.bare_flange), each maker's null tool ("KUKA $NULLFRAME"),
    and a zero live TCP of the makers of one live TCP (each maker's `bare_flange`)."""
    said: list[str] = ["tool 0"]
    zero: list[str] = []
    for m in MAKERS:
        if m.bare_flange is None:
            continue
        if any(w.target_field == "live" for w in m.protocols):
            zero.append(m.bare_flange)  # a maker of one live TCP: that TCP at zero
        else:
            said.append(m.bare_flange)  # a null tool
    if zero:
        said.append("a zero " + " or ".join(zero))
    return ", ".join(said)


#: FleetLive.no_tool's description of the bare flange (`_bare_flanges`).
BARE_FLANGES = _bare_flanges()
#: The protocols `connect` has a connector for.
CONNECTED_PROTOCOLS: frozenset[str] = frozenset(
    n for n, w in WIRE_PROTOCOLS.items() if w.connector is not None
)
#: Tool numbers each slot-addressed protocol accepts, inclusive (its maker's tool numbers).
SLOT_RANGES: dict[str, tuple[int, int]] = {
    n: w.address.numbers for n, w in WIRE_PROTOCOLS.items() if isinstance(w.address, BySlot)
}
#: Which field of a tool names its place in the controller, per protocol: "slot" (a tool
#: number) or "symbol" (ABB "TASK/MODULE/SYMBOL"; the tool's `controller_symbol`).
TARGET_FIELD: dict[str, Literal["slot", "symbol", "live"]] = {
    n: w.target_field for n, w in WIRE_PROTOCOLS.items()
}
#: (first, last) tool number by controller format, for the makers that number their tools.
TOOL_NUMBERS: dict[str, tuple[int, int]] = {
    m.format: m.tool_numbers for m in MAKERS if m.tool_numbers is not None
}
#: What each format's file is, in a few words (the console's download buttons, the README).
FILE_KINDS: dict[str, str] = {m.format: m.file_kind for m in MAKERS}
#: Preset name (as in the API, `{"preset": "ur5e"}`) -> the nominal kinematics of that arm,
#: as its maker declares it (`Maker.arms`), in MAKERS' order (the API lists them sorted).
PRESETS: dict[str, Kinematics] = {
    arm.name: arm for m in MAKERS for arm in m.arms if arm.name is not None
}
#: The pose format the pendant of each protocol's controllers shows a flange pose in (its
#: maker's): a session captured from the controller types in it unless told otherwise.
PENDANT_FORMATS: dict[str, PoseFormat] = {
    w.name: m.pose_format for m in MAKERS for w in m.protocols
}


def scope_of(protocol: str) -> DeploymentScope:
    """Where a deployment under `protocol` holds; "stored" for a protocol not known here."""
    return DEPLOYMENT_SCOPES.get(protocol, "stored")


def pose_format_of(protocol: str) -> PoseFormat | None:
    """The pose format a `protocol` controller's pendant shows; None for a protocol not
    known here."""
    return PENDANT_FORMATS.get(protocol)


def has_connector(protocol: str) -> bool:
    """Whether `connect` can open a session under `protocol` (read off its declaration, as
    `connect` reads it)."""
    wire = WIRE_PROTOCOLS.get(protocol)
    return wire is not None and wire.connector is not None


def connect(settings: ControllerSettings) -> Connector:
    """Open a session with the controller `settings` describes, by its protocol.

    Raises ControllerUnreachable when it cannot be reached within ``settings.timeout_s``,
    ControllerRefused when it refuses the session (credentials), ValueError for a protocol
    it has no connector for (`has_connector`), naming it.
    """
    wire = _wire(settings.protocol)
    if wire.connector is None:
        raise ValueError(
            f"no connector for controller protocol {settings.protocol!r} in this tcpcal yet; "
            f"connected: {', '.join(sorted(CONNECTED_PROTOCOLS))}"
        )
    return wire.connector()(settings)


def frame_writer_missing(protocol: str) -> FrameWriterMissing | None:
    """What a frame write under `protocol` would raise, known without a session: the
    FrameWriterMissing (its reason and the file to load by hand) of a connector no remote
    interface of which writes a frame (Yaskawa HSES, UR); None where one may be written."""
    wire = WIRE_PROTOCOLS.get(protocol)
    if wire is None or wire.connector is None:
        return None
    opens = wire.connector()
    if isinstance(opens, type) and issubclass(opens, FramesByHand):
        return FrameWriterMissing(opens.frame_reason, file=opens.frame_file)
    return None


def _wire(protocol: str) -> WireProtocol:
    wire = WIRE_PROTOCOLS.get(protocol)
    if wire is None:
        raise ValueError(f"unknown controller protocol {protocol!r}; known: {PROTOCOLS}")
    return wire


def port_of(settings: ControllerSettings, service: str) -> int:
    """The port of one of the protocol's services; ValueError naming the services."""
    return _wire(settings.protocol).port_of(settings, service)


def ports_in_use(settings: ControllerSettings) -> dict[str, int]:
    """Every service's port (empty for a single-service protocol)."""
    return _wire(settings.protocol).ports_in_use(settings)


def where(settings: ControllerSettings) -> str:
    """The controller's address as a message names it: "10.0.0.7:7000", or for a protocol of
    several services "10.0.0.7 (listen_node 5890, ethernet_slave 5891)"."""
    return _wire(settings.protocol).where(settings)


def target_problem(protocol: str, target: ToolTarget) -> str | None:
    """Why `target` cannot address a tool under `protocol`, in a sentence; None when it can."""
    wire = WIRE_PROTOCOLS.get(protocol)
    if wire is None:
        return f"unknown controller protocol {protocol!r}; known: {', '.join(PROTOCOLS)}"
    return wire.target_problem(target)


def check_target(protocol: str, target: ToolTarget) -> None:
    """ValueError saying what to set when `target` cannot address a tool under `protocol`."""
    problem = target_problem(protocol, target)
    if problem is not None:
        raise ValueError(problem)


def describe_target(protocol: str, target: ToolTarget) -> str:
    """The target as the controller names it: "$TOOL_DATA[3]", "UTOOL[3]", "T_ROB1/user/t";
    ValueError saying what to set when `target` cannot address a tool under `protocol`."""
    check_target(protocol, target)
    return WIRE_PROTOCOLS[protocol].describe(target)


def _maker(fmt: str) -> Maker:
    maker = BY_FORMAT.get(fmt)
    if maker is None:
        raise InvalidInput(
            "unknown-format",
            f"unknown controller format {fmt!r}; known: {', '.join(CONTROLLER_FORMATS)}",
            loc=("format",),
        )
    return maker


def export_tool(fmt: str, tool: ToolData) -> ControllerExport:
    """The tool's TCP (and load where the controller stores it) as controller `fmt`'s text."""
    return _maker(fmt).text().export(tool)


def parse_controller_text(fmt: str, text: str) -> tuple[FloatArray, FloatArray]:
    """Read controller `fmt`'s tool text -> (position (3,) mm, quaternion [w, x, y, z] (4,))."""
    if not isinstance(text, str):
        raise InvalidInput("invalid-pose", "controller text must be a string", loc=("text",))
    return _maker(fmt).text().parse(text)


def controller_file(
    fmt: str, tools: Sequence[FileTool], context: FileContext | None = None
) -> ControllerFile:
    """The file controller `fmt` loads for one tool, or (context.table) for a robot's tools."""
    return _maker(fmt).file().write(list(tools), context or FileContext())


def parse_controller_file(fmt: str, text: str) -> list[ParsedTool]:
    """Every tool of a controller `fmt` file, as `controller_file` writes it (or the
    controller saves it)."""
    if not isinstance(text, str):
        raise InvalidInput("invalid-pose", "controller file must be text", loc=("text",))
    return _maker(fmt).file().read(text)


def export_frame(fmt: str, frame: FrameData) -> ControllerExport:
    """The frame (a base, a fixed tool) as controller `fmt`'s text."""
    return _maker(fmt).frame().export(frame)


def parse_frame_text(fmt: str, text: str) -> tuple[FloatArray, FloatArray]:
    """Read controller `fmt`'s frame text -> (position (3,) mm, quaternion [w, x, y, z])."""
    if not isinstance(text, str):
        raise InvalidInput("invalid-pose", "controller text must be a string", loc=("text",))
    return _maker(fmt).frame().parse(text)


def frame_file(
    fmt: str, frames: Sequence[FileFrame], context: FileContext | None = None
) -> ControllerFile:
    """The file controller `fmt` loads for one frame, or (context.table) a robot's frames."""
    return _maker(fmt).frame().write(list(frames), context or FileContext())


def parse_frame_file(fmt: str, text: str) -> list[ParsedFrame]:
    """Every frame of a controller `fmt` frame file, as `frame_file` writes it (or the
    controller saves it)."""
    if not isinstance(text, str):
        raise InvalidInput("invalid-pose", "controller file must be text", loc=("text",))
    return _maker(fmt).frame().read(text)


def vendor_formats(vendor: str | None) -> tuple[str, ...]:
    """The controller formats a robot of `vendor` loads (every format when not known): the
    first maker whose vendor word it contains ("Yaskawa Motoman"), else the first whose
    initials stand as a word in it ("UR10e", "TM5")."""
    key = (vendor or "").lower()
    for maker in MAKERS:
        if any(word in key for word in maker.vendor_words):
            return (maker.format,)
    words = set(re.findall(r"[a-z]+", key))
    for maker in MAKERS:
        if words & set(maker.vendor_initials):
            return (maker.format,)
    return CONTROLLER_FORMATS


def vendor_protocols(vendor: str | None) -> tuple[str, ...]:
    """The protocols a robot of `vendor`'s controller speaks (its maker's, as
    `vendor_formats` finds the maker; every protocol when the vendor is not known)."""
    formats = vendor_formats(vendor)
    if formats == CONTROLLER_FORMATS:
        return tuple(WIRE_PROTOCOLS)
    return tuple(wire.name for wire in BY_FORMAT[formats[0]].protocols)


def vendor_speaks(vendor: str | None, protocol: str) -> bool:
    """Whether a robot of `vendor`'s controller speaks `protocol` (any protocol when the
    vendor names no maker known here): the one test of a controller's protocol against its
    robot's vendor, on PUT of the controller and on PATCH of the vendor."""
    return protocol in vendor_protocols(vendor)


def vendor_maker(vendor: str | None) -> Maker | None:
    """The maker of a robot of `vendor` (as `vendor_formats` finds it); None when the vendor
    names no maker known here."""
    formats = vendor_formats(vendor)
    return None if formats == CONTROLLER_FORMATS else BY_FORMAT[formats[0]]


def vendor_frame_problem(vendor: str | None, target: FrameTarget) -> str | None:
    """Why `target`, a frame being registered on a robot of `vendor` (its slot or symbol, as
    given: either may be left for later), names no frame of that robot's controllers: the
    check each protocol of its maker makes at deployment (`WireProtocol.frame_problem`);
    None when it names one, or when the vendor names no maker known here."""
    maker = vendor_maker(vendor)
    if maker is None:
        return None
    for wire in maker.protocols:
        problem = wire.frame_problem(target, given_only=True)
        if problem is not None:
            return problem
    return None


def vendor_pose_format(vendor: str | None) -> PoseFormat | None:
    """The pose format the pendant of a robot of `vendor` shows (its maker's, as
    `vendor_formats` finds the maker); None when the vendor names no maker known here."""
    formats = vendor_formats(vendor)
    if formats == CONTROLLER_FORMATS:
        return None
    return BY_FORMAT[formats[0]].pose_format
